"""Triangle meshes as fixtures: reading a file (:mod:`.load`), the tables of the proximity query (:mod:`.tables`: a
BVH and pseudo-normals), its C source and the compiled CasADi external (:mod:`.external`), and a brute-force
reference in NumPy (:mod:`.brute`)."""
