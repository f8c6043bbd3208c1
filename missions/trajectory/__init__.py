"""From a planned path to timed drone motion: tracks, waypoints, legs, flight plan."""
