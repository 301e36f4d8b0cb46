"""The paper's likelihood as described, a render per particle: kept to compare with the vectorized
one (``benchmarks/paper_faithful.py``)."""
