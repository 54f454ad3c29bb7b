"""Scan → collision mesh stage (Open3D, trimesh).

``build_meshes(scans_dir, out_dir, config, force=False) -> BuildReport`` turns every
``.ply .pcd .xyz .pts`` point cloud of a folder into ``<name>.obj`` — plain ``v``/``f``
lines, vertices in **metres** — plus ``manifest.json`` (inputs, parameters, versions,
timings, quality metrics, bounding boxes in metres). Open3D is imported only when a
scan is built.

Modules: ``io`` (read/write files), ``units``, ``load`` (file → down-sampled cloud, mm),
``clean`` (voxels, outliers, normals), ``reconstruct`` (surface + trimming), ``refine``
(cleaning, simplification, max edge), ``metrics``, ``manifest``, ``build`` (orchestration,
parallelism, skip logic), ``synthetic`` (example-scan generator).
"""

from pipeline.meshes.build import BuildReport, ScanResult, build_meshes

__all__ = ["BuildReport", "ScanResult", "build_meshes"]
