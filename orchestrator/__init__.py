"""The co-simulation master, scenarios, SSP, campaigns, jitter metrics, reports and CLI."""
