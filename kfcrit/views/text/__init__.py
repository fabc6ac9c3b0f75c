"""Plain-text views: the terminal summary and the file-key reference."""
