"""The bench's direct loop: the bridge's I/O and the control chain in one thread of one process."""
