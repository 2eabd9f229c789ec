"""CLI commands, one module each (discovered by scanamp.cli)."""
