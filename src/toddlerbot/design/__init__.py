"""Design metrics of the appendix (sections 8.2, 8.4-8.6), computed from the robot spec and the motor catalogue."""
