"""Several photos -> 3D tree (seed 002, Tan et al. 2007): see :mod:`.pipeline`."""
