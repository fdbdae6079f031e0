-- Where a snippet leads: itself and up to two play-on snippets (each starting on the previous one's last
-- frame, in the same clip version and mirror image), composed from their net motions. The objective of
-- select_next_snippet measures this, so that a choice that leads into a turn is seen as turning: a
-- snippet's own 0.5 s says little about where the clip goes (a turn clip's lead-in walks straight).

CREATE FUNCTION modb.fill_futures()
RETURNS bigint
LANGUAGE sql VOLATILE PARALLEL UNSAFE
BEGIN ATOMIC
    WITH chain AS (
        SELECT s.id, s.net_translation AS t0, s.net_heading AS h0,
               a.net_translation AS t1, coalesce(a.net_heading, 0) AS h1,
               b.net_translation AS t2, coalesce(b.net_heading, 0) AS h2
          FROM modb.snippets s
          LEFT JOIN modb.snippets a ON a.clip_id = s.clip_id AND a.version = s.version AND a.mirrored = s.mirrored
                                   AND a.first_frame = s.first_frame + s.n_frames - 1
          LEFT JOIN modb.snippets b ON b.clip_id = a.clip_id AND b.version = a.version AND b.mirrored = a.mirrored
                                   AND b.first_frame = a.first_frame + a.n_frames - 1
         WHERE s.future_translation IS NULL
    ), updated AS (
        UPDATE modb.snippets s
           SET future_translation = ARRAY[
                   c.t0[1] + coalesce(c.t1[1] * cos(c.h0) + c.t1[3] * sin(c.h0), 0)
                           + coalesce(c.t2[1] * cos(c.h0 + c.h1) + c.t2[3] * sin(c.h0 + c.h1), 0),
                   c.t0[2] + coalesce(c.t1[2], 0) + coalesce(c.t2[2], 0),
                   c.t0[3] + coalesce(c.t1[3] * cos(c.h0) - c.t1[1] * sin(c.h0), 0)
                           + coalesce(c.t2[3] * cos(c.h0 + c.h1) - c.t2[1] * sin(c.h0 + c.h1), 0)],
               future_heading = atan2(sin(c.h0 + c.h1 + c.h2), cos(c.h0 + c.h1 + c.h2))
          FROM chain c
         WHERE c.id = s.id
        RETURNING 1)
    SELECT count(*) FROM updated;
END;
COMMENT ON FUNCTION modb.fill_futures() IS
    'Fills future_translation and future_heading of the snippets that lack them (build_snippets calls it); returns how many';
REVOKE EXECUTE ON FUNCTION modb.fill_futures() FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.fill_futures() TO modb_loader;
