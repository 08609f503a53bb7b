"""Readers: the only code that parses input bytes; every record keeps its source line."""
