"""Editing what is stored: a clip version's meta (annotations, tags) with optimistic concurrency,
shared by `modb annotate` and the REST interface."""
