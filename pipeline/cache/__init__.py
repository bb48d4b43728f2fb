"""Work reused between runs, keyed by the code that made it (codekey)."""
