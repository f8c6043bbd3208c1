"""FlyCrane model: system, kinematics, statics, feasibility and cost (no MAVLink, no HTTP)."""
