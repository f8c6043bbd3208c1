"""Planner benchmarks and path profiles (the paper's Table I and Fig. 6)."""
