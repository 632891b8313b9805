"""ToddlerBot: an open-source software stack for the ToddlerBot humanoid."""

__version__ = "0.2.0"
