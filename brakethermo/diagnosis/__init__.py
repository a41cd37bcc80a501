"""The diagnosis engine: reference model, held-out split, candidates, verdicts (any model)."""
