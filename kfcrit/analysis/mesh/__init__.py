"""Multi-hop meshes in the analysis (theory §13): the typed ``mesh`` section
(:mod:`kfcrit.analysis.mesh.section`) and its construction (:mod:`kfcrit.analysis.mesh.build`)."""
