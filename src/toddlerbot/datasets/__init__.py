"""Demonstration datasets, needing no robot: raw episodes, LeRobot v3.0 files (writer, validating reader), the
numpy training copy and windows, and a Rerun view of a dataset (`view`, extra ``[viz]``)."""
