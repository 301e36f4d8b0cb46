"""Rendering with Mitsuba 3: training splits, flights, the denoiser, the one-worker pipeline."""
