-- A change of the match profiles takes a new generation of the plans sessions cache (69_generations.sql).

CREATE TRIGGER match_profiles_generation AFTER INSERT OR UPDATE OR DELETE OR TRUNCATE ON modb.match_profiles
    FOR EACH STATEMENT EXECUTE FUNCTION modb.next_generation('match_plans');
