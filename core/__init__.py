"""Contracts every stage shares: dataset format and readers, poses and camera geometry,
classes, atomic file I/O, config checks and the output-folder policy."""
