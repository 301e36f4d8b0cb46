"""The particle filter and its parts: motion, likelihood, projection, visibility, hypotheses."""
