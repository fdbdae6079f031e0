-- 0.3.0: synthesis in the database (modb.synthesize and its helpers), and the default and strict
-- profiles retuned for seams that look like natural steps.
-- Indexes for the snippets -> terminators foreign keys: without them, replacing or deleting snippets of
-- many clips scanned every snippet once per terminator (minutes for 115k snippets; 1.5 s with them).
CREATE INDEX snippets_begin_terminator_idx ON modb.snippets (begin_terminator);
CREATE INDEX snippets_end_terminator_idx ON modb.snippets (end_terminator);
--@include 73_profiles.sql
--@include 78_synthesize.sql
