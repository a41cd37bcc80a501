"""Pipelines: file -> session -> model + filter -> results. No CLI, no rendering."""
