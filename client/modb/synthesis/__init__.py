"""Motion synthesis: a chain's vocabulary (chain), the Avatar that walks it live (avatar), strips
written toward goals (synth), where snippets are placed (placement), their source frames
(source_frames), the quality report (quality) and transition graphs (graphs)."""
