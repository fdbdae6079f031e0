"""`modb demo`: the run (run) and the real capture it uses (data)."""
