"""Statistical motion models of primitives: built from processed data (build.py, scikit-learn),
turned back into motion by the kernel (modb_kernel.motion_model)."""
