"""Database access: the embedded cluster (cluster), which database a command uses (dsn), connections
with modb's types and session settings (connection), PostgreSQL array text (pgarray)."""
