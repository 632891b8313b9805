"""Motor system identification: test-bed analysis, excitation profiles, logs and rigs, and the 9-parameter fit."""
