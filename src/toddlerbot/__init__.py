"""ToddlerBot: an open-source software stack for the ToddlerBot humanoid."""

__version__ = "0.1.0"
