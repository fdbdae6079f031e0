"""Numeric core shared by the Python client and the server's PL/Python functions.

Plain numpy only (no numpy 2.x-only API): the server runs Debian's python3 with
numpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this
package is loaded from the extension's install script (see
``extension/build_sql.py``), so the server always runs the code of the
installed extension version.

Conventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),
unit length, w >= 0; a joint's rotation is relative to its parent.
"""
