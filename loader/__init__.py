"""Parsers for motion-capture files and their ingest into the modb schema."""
