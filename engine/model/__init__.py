"""The scene model, free of numba: the validated scene (``spec``, ``spec_bodies``,
``spec_common``), the bristles' rest layout (``layout``), body shapes as meshes (``meshes``,
with the bounds a mesh file is checked against before parsing: ``mesh_limits``) and the
reduced brush law's file (``reduced_law``)."""
