"""A simulated ArduCopter for tests: protocol, parameters and a kinematic flight."""
