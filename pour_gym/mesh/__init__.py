"""Chapter 3 of the thesis: from a point cloud to a container mesh, and meshes measured.

- :mod:`~pour_gym.mesh.scan`: a simulated turntable depth scan (``PointCloud``).
- :mod:`~pour_gym.mesh.gaussian_field`: the Gaussian-kernel implicit surface.
- :mod:`~pour_gym.mesh.reconstruct`: implicit surface -> marching cubes -> normals ->
  Laplacian smoothing.
- :mod:`~pour_gym.mesh.modelgen`: the whole chapter on a thesis object, with the report
  against its ground truth (Tables 4.1-4.3).
- :mod:`~pour_gym.mesh.measure`: label-free geometry of any mesh (height, rim radius,
  holding volume, opening, Chamfer distance).
- :mod:`~pour_gym.mesh.fileio`: point clouds and meshes read and written (PLY, PCD, XYZ,
  NPY; OBJ, STL, PLY, GLB, OFF).
"""
