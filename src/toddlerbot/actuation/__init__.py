"""Motor catalogue and the actuator model (bottom layer: imports nothing else from toddlerbot)."""
