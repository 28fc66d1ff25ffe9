"""The search family: breadth-first, fastest, parallel and liveness searches and their tables."""
