"""The view-model's panels: one class per part of the window, no widget.

Each panel holds its own state and actions and reaches the others through
the :class:`~qogi_gui.viewmodel.ViewModel` it belongs to (``self.vm``), which
also holds what they share: the ``qogi`` API, the user store, the clock, the
message log, the open recording and the revision counters (``vm.rev``).
Each has ``reset(recording)``, called when a recording is opened.

============  ============  =================================================
attribute     file          what it holds and does
============  ============  =================================================
``log``       messages.py   what the user is told (info, warnings, errors)
``file``      recording.py  opening recordings and camera files, the demo
``player``    playback.py   frame, play/pause, speed, the recording's clock
``video``     video.py      how the frame is drawn, the pixel read-out
``overlay``   overlay.py    the result's maps on the video (column, vectors)
``editor``    drawing.py    control surfaces, background region, source pick
``form``      analysis.py   the analysis form and its per-field messages
``work``      work.py       the background job slot (open, demo, run)
``run``       run.py        the quantification and the result it returned
``exporter``  exports.py    files out
============  ============  =================================================
"""
