"""Walking pattern generation: ZMP preview control, footstep plans, swing trajectories and leg IK (numpy only)."""
