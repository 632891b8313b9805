"""Declared skill chains: an ordered list of skills read from a YAML file, each run until its switch
condition holds, on any `Robot` (sim or real) — see `spec` (file format), `predicates`, `skills`, `runner`."""
