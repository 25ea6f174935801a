"""The condensed reduced model, split by job (see ``nlp`` for the formulation)."""
