"""Process exit codes shared by every trackside command."""

OK = 0
FINDINGS = 1  # the input had findings the user asked to fail on (--strict)
USAGE = 2  # bad options, unreadable or missing input, output that cannot be written
INTERRUPTED = 130  # 128 + SIGINT: stopped by Ctrl-C, as a shell reports it; no partial output file left
TERMINATED = 143  # 128 + SIGTERM: stopped by kill or a service manager; no partial output file left
