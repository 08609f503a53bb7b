"""Readers: the only code that parses input bytes; every record keeps its source line.

CAM formats are packages registered by name (:mod:`prs3_post.readers.registry`) behind one protocol
(:mod:`prs3_post.readers.protocol`): ``cl/`` (APT CL) and ``gcode/`` (3+2 G-code; ``fivex/`` reads 5-axis
G-code under TCP for it), each as ``reader`` (entry points and the stream), ``summary`` (what a file
read holds), the syntax and the semantics of its records, and ``bulk`` (the byte, numpy and C passes).
A new format is a new package with a :class:`~prs3_post.readers.protocol.Reader` and one
:func:`~prs3_post.readers.registry.register` call; ``convert`` names none of them. ``program`` reads our
own output; ``poses``, ``tooltable`` and ``jobfile`` the other inputs.
"""
