"""The simulator: trains, sensors, GNSS devices and faults, with a ground truth."""
