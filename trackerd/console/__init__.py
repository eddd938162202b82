"""The operator's console: live camera views, wall map, status, actions, metrics (docs/console.md)."""
