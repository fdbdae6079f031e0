"""MoDB for PostgreSQL: the Python client (loading, export, the embedded database)."""

__version__ = "0.1.0"
