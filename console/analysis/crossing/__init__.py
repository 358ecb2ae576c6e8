"""Level crossings: the crossing unit (warn, hold, give the road back), its estimates and bounds, and the
yardsticks."""
