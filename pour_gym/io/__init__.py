"""Files, output and native libraries: the cache folder, stdout, open3d, the TBB wheel."""
