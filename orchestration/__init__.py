"""Co-simulation master: scenarios, the unit interface, the stepping algorithm, execution and recording."""
