"""Studies built on the master: the case study, SOSM tuning, sweeps."""
