"""The scene model, free of numba: the validated scene (``spec``, ``spec_bodies``,
``spec_common``), the bristles' rest layout (``layout``), body shapes as meshes (``meshes``),
prescribed motions (``motion``) and the reduced brush law's file (``reduced_law``)."""
