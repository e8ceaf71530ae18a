"""The application: closed-loop runtime, CLI (`python -m app`), hardware bridge and the viser studio."""
