"""The real capture `modb demo` and the benchmarks load (data); the demo's steps are in
modb.cli.demo_run."""
