"""HTTP layer: routers, dependencies and the problem+json mapping."""
