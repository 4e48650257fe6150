"""Tasks: reward and success only; the env base does the rest (architecture.md)."""
