"""Scan → collision mesh stage (Open3D, trimesh).

``build.build_meshes(scans_dir, out_dir, config, force=False) -> BuildReport`` turns every
``.ply .pcd .xyz .pts`` point cloud of a folder into ``<name>.obj`` — plain ``v``/``f``
lines, vertices in **metres** — plus ``manifest.json`` (inputs, parameters, versions,
timings, quality metrics, bounding boxes in metres). The package imports none of its
modules, so reading a manifest or an OBJ does not load Open3D, which building a scan needs.

Modules: ``io`` (read/write files), ``units``, ``load`` (file → down-sampled cloud, mm),
``clean`` (voxels, outliers, normals), ``reconstruct`` (surface + trimming), ``refine``
(cleaning, simplification, max edge), ``metrics``, ``manifest``, ``build`` (orchestration,
parallelism, skip logic), ``synthetic`` (example-scan generator).
"""
