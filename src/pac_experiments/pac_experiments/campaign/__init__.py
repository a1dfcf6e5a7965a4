"""Campaigns: a YAML grid of scenario points run in chunks (serially or on Dask), their results,
reports and summaries."""
