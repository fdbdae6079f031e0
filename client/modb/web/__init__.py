"""The local web app: `modb serve`."""
