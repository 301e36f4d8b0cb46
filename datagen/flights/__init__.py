"""Flights: routes through the free space, trajectories, the free space's local axes."""
