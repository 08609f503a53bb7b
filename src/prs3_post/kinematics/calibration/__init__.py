"""Calibration of a general 3-PRS head from measured tool poses: the error model (which parameters,
how they are scaled), identification by nonlinear least squares with an identifiability analysis,
the choice of measurement poses, and the first-order propagation of uncertainties to the tool.

Pure numpy and scipy: no files. The use cases (``prs3-post calibrate``, ``calibrate plan``,
``accuracy``) are in :mod:`prs3_post.app.calibrate` and :mod:`prs3_post.app.accuracy`.
"""
