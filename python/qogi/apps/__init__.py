"""The applications on top of the library: the command line (:mod:`.cli`),
batch runs on Dask (:mod:`.batch`), reports (:mod:`.report`), ``qogi info``
and the probability of detection (:mod:`.detectability`). Nothing below
imports them; the viewer (``qogi_gui``) is found as an optional app."""
