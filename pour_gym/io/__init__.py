"""Where files and output go: the cache folder, stdout redirection, open3d's loader."""
