"""Result objects and the figures computed from them: what pipelines produce and pages,
writers and the CLI read. Below both (it imports no pipeline and no page)."""
