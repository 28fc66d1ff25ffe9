"""The language front end: source text and world files to a checked program."""
