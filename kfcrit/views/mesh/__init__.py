"""Views of a mesh record (theory §13): terminal lines, the report section and the topology map."""
