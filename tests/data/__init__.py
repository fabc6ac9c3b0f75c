"""Facts from the papers and the shared benchmark generator, kept in the repository."""
