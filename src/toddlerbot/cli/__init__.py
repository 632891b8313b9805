"""The `toddlerbot` command line: one sub-command group per area."""
