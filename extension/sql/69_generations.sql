-- What a session's caches were read at (src/block_directory.c, src/selection_plan.c): every change of
-- the tables behind one takes a new number from the sequence (never reused, even by a transaction that
-- rolls back). Writers queue on their row, so the number a snapshot sees names exactly what it sees.
CREATE SEQUENCE modb.generation_seq;
CREATE TABLE modb.generations (
    name       text PRIMARY KEY,
    generation bigint NOT NULL
);
COMMENT ON TABLE modb.generations IS
    'The number of the last change of what a session caches for select_next_snippets: snippet_blocks (its block directory), match_plans (profiles and graphs, its resolved plans)';
INSERT INTO modb.generations VALUES ('snippet_blocks', nextval('modb.generation_seq')),
                                    ('match_plans', nextval('modb.generation_seq'));

CREATE FUNCTION modb.next_generation()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    UPDATE modb.generations SET generation = nextval('modb.generation_seq') WHERE name = TG_ARGV[0];
    RETURN NULL;
END
$$;
COMMENT ON FUNCTION modb.next_generation() IS
    'Trigger (argument: a modb.generations name): a change takes a new generation, and sessions read what they cached again';
CREATE TRIGGER graphs_generation AFTER INSERT OR UPDATE OR DELETE OR TRUNCATE ON modb.graphs
    FOR EACH STATEMENT EXECUTE FUNCTION modb.next_generation('match_plans');

GRANT SELECT ON modb.generations TO modb_reader;
-- Writers of what is cached take the new generation themselves (the triggers run as the writing role).
GRANT UPDATE (generation) ON modb.generations TO modb_loader;
GRANT USAGE ON SEQUENCE modb.generation_seq TO modb_loader;
