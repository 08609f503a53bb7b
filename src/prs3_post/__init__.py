"""prs3-post: the post-processor for 3-PRS parallel-kinematic machines."""

__version__ = "0.1.0"
