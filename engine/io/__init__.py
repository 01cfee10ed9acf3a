"""Files: the HDF5 recorder and reader (``recorder``, ``results``), output-path checks
(``output_paths``) and exports (``xdmf``, ``vtk_export``)."""
