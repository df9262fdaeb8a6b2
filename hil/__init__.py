"""The loop and the product surface: scheduler, safety supervisor, experiments, logs, CLI."""
