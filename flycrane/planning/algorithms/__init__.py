"""The planners: T-RRT, bitrrt and their kernels, OMPL's peers."""
