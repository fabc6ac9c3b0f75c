"""The HTML/PDF design-review report: view models of the record's sections and the renderer."""
