-- complain if script is sourced in psql, rather than via CREATE EXTENSION
\echo Use "CREATE EXTENSION modb CASCADE" to load this file. \quit

-- Created here, not through the control file's `schema`, so the schema is a member of the
-- extension and DROP EXTENSION removes it.
CREATE SCHEMA modb;
COMMENT ON SCHEMA modb IS 'MoDB: motion-capture clips, skeletons, collections, models and graphs';
