"""The policy loop: command sources, the fixed-rate runner, run logs, summaries and plots."""
