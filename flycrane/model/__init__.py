"""The FlyCrane's model: system, kinematics, statics, feasibility and cost."""
