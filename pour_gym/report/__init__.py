"""What people look at: markdown and text tables, pictures of meshes and clouds, videos."""
