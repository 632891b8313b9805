"""What the commands that run a robot assemble before the one run loop, as library calls a script can make: the
robot, the policy, the watchers and the clock (`sim` for `sim run`, `robot` for `hw run` and a chain on the real
robot, `teleop` for `teleop`). The command line only parses, calls them and prints."""
