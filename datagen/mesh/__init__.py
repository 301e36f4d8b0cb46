"""The classed mesh of a building and the model edges extracted from it."""
