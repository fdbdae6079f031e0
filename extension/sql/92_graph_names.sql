-- Graph names, in a table no selection reads: a graph is deleted by deleting its name here, and its
-- modb.graphs row, stored snippets and transitions go with it (ON DELETE CASCADE, run as the owner). So the
-- loader needs no DELETE on modb.graphs, which every selection reads (a DELETE grant would also let it LOCK
-- that table against every reader).
CREATE TABLE modb.graph_names (
    name text NOT NULL,
    kind text NOT NULL,
    PRIMARY KEY (name, kind)
);
COMMENT ON TABLE modb.graph_names IS
    'The name and kind of every graph in modb.graphs: deleting a row here deletes that graph with its rows';
INSERT INTO modb.graph_names (name, kind) SELECT name, kind FROM modb.graphs;  -- on update: the graphs so far
ALTER TABLE modb.graphs ADD FOREIGN KEY (name, kind) REFERENCES modb.graph_names ON DELETE CASCADE;
SELECT pg_catalog.pg_extension_config_dump('modb.graph_names', '');

GRANT SELECT ON modb.graph_names TO modb_reader;
GRANT INSERT, DELETE ON modb.graph_names TO modb_loader;
GRANT INSERT (name, kind, skeleton_id, data, meta) ON modb.graphs TO modb_loader;
GRANT UPDATE (skeleton_id, data, meta) ON modb.graphs TO modb_loader;
