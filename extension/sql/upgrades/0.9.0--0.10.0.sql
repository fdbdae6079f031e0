-- 0.10.0: select_next_snippets in C. The 0.9.0 SQL function becomes select_next_snippets_reference, the
-- statement of the rule; select_next_snippets computes the same rows without planning a query per call
-- (src/selection.c), searching boxes over snippet blocks instead of the GiST index, and
-- modb.explain_selection shows how a call ran. The session knobs become real settings when the library
-- is loaded (src/settings.c: nothing to create in SQL); match_plan reads 'profile' as the profile's value.
--@include 69_generations.sql
--@include 71_snippet_blocks.sql
--@include 76_match_profiles_generation.sql
-- The blocks of every stored snippet (one call per clip source, so no call reads more than a clip).
SELECT count(modb.add_snippet_blocks(ids))
  FROM (SELECT array_agg(id) AS ids FROM modb.snippets GROUP BY clip_id, version, mirrored) s;
--@include 79_match_plan.sql
--@include 87_select.sql
