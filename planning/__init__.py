"""Traversability margins and traction planning (not yet built: see the project's issues)."""
__all__: list[str] = []
