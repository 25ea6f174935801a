"""What a weft solve gives back: the typed result and its JSON (``results``, ``reactions``),
full-versus-reduced comparisons (``comparison``), pictures (``plot``), loading paths
(``path``), centreline exports (``export``) and the terminal summaries (``summary``)."""
