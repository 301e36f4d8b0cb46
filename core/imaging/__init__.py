"""Cameras, lenses, colour, camera effects, the realism settings and Mitsuba ray casts."""
