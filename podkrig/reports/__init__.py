"""Figures and HTML reports: they read result objects and never compute them."""
