"""Recordings: folders and ROS bags read into frame sources, and flights exported as recordings."""
