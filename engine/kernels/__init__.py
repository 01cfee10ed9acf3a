"""The engine's numba kernels: pure functions over the flat arrays of ``engine.state``.

One module per part of the physics: ``bonds`` (beam bonds between the nodes of a bristle),
``contacts`` (bristle-bristle), ``body_contacts`` (bristle-body, body-body), ``mesh_contact``
(mesh-mesh), ``contact_law`` (the normal and friction law they share), ``bodies`` (rigid-body
integration), ``orbit`` (relative orbital dynamics), ``control`` (pose controllers and loads),
``rotations`` and ``geometry`` (quaternions, closest points), ``neighbours`` (when the
neighbour lists are rebuilt, the rebuild, its overflow codes), and ``stepper`` (the step loop
that calls them); ``jit`` holds the compile flags of the per-item kernels.

Importing this package imports nothing: each module compiles (or loads from numba's cache in
``engine/kernels/__pycache__``) when it is imported.
"""
