"""Train integrity: whole, in doubt or parted, from the GNSS, counters' and sections' witnesses."""
