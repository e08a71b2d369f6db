"""What is measured from frames: column densities by per-pixel inversion of
the forward model (:mod:`.inversion`, the mixing-line search
:mod:`.mixing_line`), gas motion by velocimetry (:mod:`.velocimetry`) and
the flux integral across a control surface (:mod:`.flux`). Above the
physics layer, below io and the pipeline."""
