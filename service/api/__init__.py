"""HTTP API of the service, versioned under /v1."""
