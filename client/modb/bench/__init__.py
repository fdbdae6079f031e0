"""The benchmarks of `modb bench`, one module each: load (parse and load speed), select (selection
latency), synth (a seeded course), scale (selection at several database sizes, with its baselines
and the speed-resampled data of its largest size). Results and how they were run: BENCHMARKS.md."""
