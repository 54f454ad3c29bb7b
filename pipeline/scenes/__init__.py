"""What the world is: obstacles (pegs, walls, edges, meshes) in the world frame, SI units."""

from pipeline.scenes.obstacles import Box, Cylinder, Scene, TriangleMesh
from pipeline.scenes.library import active_pegs, collision_edge, empty, mesh_scene, passive_peg, wall

__all__ = ["Box", "Cylinder", "Scene", "TriangleMesh", "active_pegs", "collision_edge", "empty",
           "mesh_scene", "passive_peg", "wall"]
