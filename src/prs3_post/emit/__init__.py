"""Output: the G-code emitter, the program header (written and read back), pose tables and safe output files."""
