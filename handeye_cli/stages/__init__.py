"""The pipeline stages between reading and solving: sync (association, time offset), gates, pairs."""
