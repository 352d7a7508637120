"""Bilimovich Explorer web app (Panel). Holds no numerics: it calls explorer_core."""
