"""What the technician sees during and after a test: the live panel on a terminal, log lines elsewhere."""
