"""Motion planning for the FlyCrane: state space, validity, objective, planners, smoothing."""
