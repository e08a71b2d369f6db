"""The window's panels: one class per part of the Dear PyGui window.

Each takes the :class:`~qogi_gui.app.App` it belongs to, builds its widgets
(``build``), forwards their input to the view-model (``app.vm``) and redraws
from it (``refresh*``); :class:`~qogi_gui.app.App` lays them out and calls
their refreshers when the view-model's revision counters say something
changed. Widget tags are global (Dear PyGui's), so scripts and the smoke test
reach any widget through :meth:`App.press`.

==================  ====================================================
theme.py            colours, plot themes, colour maps
panel.py            Panel: what every panel holds (the App, its view-model)
recording_tab.py    Recording tab: open, demo, recent files, metadata
display_tab.py      Display tab: channel, quantity, colours, range, overlay
surfaces_tab.py     Surfaces tab: click mode, surface list, region
analysis_tab.py     Analysis tab: the form, per-field messages, Run
results_tab.py      Results tab and exports; the rate time series plot
image_view.py       the image: frame, overlay, surfaces drawn, mouse, keys
playback_bar.py     the controls below the image
status_bar.py       progress, cancel, messages, frame rate
dialogs.py          file dialogs, the message pop-up, the scene-facts form
==================  ====================================================
"""
