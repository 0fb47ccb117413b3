"""The project's own tools: generators of docs/ (reports) and research scripts (scripts); not installed."""
