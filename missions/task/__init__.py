"""A task end to end: its schema, its resolution, its directory and its run."""
