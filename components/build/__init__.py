"""Build tooling: pythonfmu units, the plain-C isolator, pythonfmu's exit-hook fix."""
