"""The labs' steps onto real data: one module per lab, each a function the notebook calls."""
