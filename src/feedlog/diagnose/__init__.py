"""feedlog.diagnose: what the simulation gets wrong on measured data, the named cause, the gain."""
