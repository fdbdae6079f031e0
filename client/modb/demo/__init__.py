"""The real capture `modb demo` and the benchmarks load (data), which of its clips the demo's
family of motion models learns from (runs); the demo's steps are in modb.cli.demo_run and
modb.cli.demo_models."""

MODEL_GRAPH = "demo"  # the demo's graph of motion models (its transition graph has the same name)
