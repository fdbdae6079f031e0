"""Who may write through the REST interface: access tokens (tokens.py) and the audit log of what
each write did (audit.py)."""
