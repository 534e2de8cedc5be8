"""Held-out evaluation of a model, by job: metrics (NumPy), segments (VAE and prior against a baseline),
rollouts (sessions from real clips and the scripted interaction scenarios) and plots. The command line and
the report are model_runtime.evaluate."""
