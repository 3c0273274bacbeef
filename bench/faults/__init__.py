"""``roverops bench faults``: mobility fault protection and injected faults."""
