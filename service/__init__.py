"""FlyCrane mission service: the HTTP API, its storage and background jobs."""
