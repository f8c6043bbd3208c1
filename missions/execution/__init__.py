"""Playing the plan from one clock: the group clock, the team failsafe, the vehicles'
modes, the ground's target stream, the onboard player and the check before the release."""
