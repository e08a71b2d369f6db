"""The physics layer: spectroscopy (HITRAN lines, cross-sections), optics
(Planck, spectral responses), radiometry, the forward model (radiative
transfer through the plume seen by each channel), the camera and its
presets. It uses only the base modules (errors, files, cache, contract) and
the engine."""
