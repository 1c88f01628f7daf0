"""Benchmarks of marinejax (run them with `marinejax bench <name>`)."""
