"""FlyCrane missions: drone tracks, MAVLink missions, file formats, logs and uploads."""
