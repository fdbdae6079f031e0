-- complain if script is sourced in psql, rather than via CREATE EXTENSION
\echo Use "CREATE EXTENSION modb CASCADE" to load this file. \quit

COMMENT ON SCHEMA modb IS 'MoDB: motion-capture clips, skeletons, collections, models and graphs';
