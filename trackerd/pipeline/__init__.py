"""The real-time pipeline: bounded queues, figures, and the daemon that ties source, locator and publisher."""
