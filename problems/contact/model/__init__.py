"""The contact model and its scenes: the scene (2D and 3D) and its files, meshes, expressions, the assembly of K, f, B and the lumped boundary mass, custom geometries, the memory check."""
