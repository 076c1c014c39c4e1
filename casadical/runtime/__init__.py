"""The run time under every layer: thread limits, Ctrl-C and SIGTERM, safe file writing."""
