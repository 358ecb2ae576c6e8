"""Process exit codes shared by every trackside command."""

OK = 0
FINDINGS = 1  # the input had findings the user asked to fail on (--strict)
USAGE = 2  # bad options, unreadable or missing input
