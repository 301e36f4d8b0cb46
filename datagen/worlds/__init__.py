"""Worlds: the procedural corridor and floors, imported buildings built into sites and scenes."""
