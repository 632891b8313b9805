"""Motor system identification: test-bed analysis, excitation profiles, logs and rigs, the 9-parameter and
extended fits, and recording on a real motor."""
