-- 0.14.0: the write side of the REST interface, and selection by annotation. Access tokens, stored as
-- their sha256 only (modb.access_tokens, read through modb.token_grant), an insert-only audit log of every
-- write (modb.audit_log), and the annotations knob and profile field (modb.annotation_spec,
-- modb.annotated; the plan's new field, read by match_plan, select_next_snippets_reference and the C path).
--@include 93_access_tokens.sql
--@include 94_audit_log.sql
ALTER TYPE modb.match_plan ADD ATTRIBUTE annotations text[];
COMMENT ON TYPE modb.match_plan IS
    'A profile resolved for one query: included joints (0-based standard indices), thresholds per standard joint (Infinity when not included), the half-widths of the search box per feature, the objective''s weights, the transition graph (modb.graphs id) candidates must belong to, if any, whether the objective looks one snippet further through it, whether it ranks by the graph''s cost-to-go, and the annotation names candidates keep to (modb.annotation_spec), if any';
--@include 78_annotations.sql
--@include 79_match_plan.sql
--@include 87_select.sql
-- modb.synthesize takes annotations (a new last parameter: the old signature goes, or calls would be ambiguous)
DROP FUNCTION modb.synthesize(float8[], int, bigint, float8[], float8, text, text, float8, float8);
--@include 89_synthesize.sql
-- Editing the catalogue (collections, clips, versions) and clips cut at annotated segments
--@include 95_catalog_edits.sql
--@include 96_clip_segments.sql
