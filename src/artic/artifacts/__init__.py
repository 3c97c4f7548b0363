"""Stage outputs on disk: folders, manifests, atomic writes, content hashes, file formats.

Together with `cli/`, the only package that touches the file system.
"""
