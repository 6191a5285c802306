"""Physics cores: pure functions and small classes in SI units, no FMI (fast tests without building an FMU)."""
