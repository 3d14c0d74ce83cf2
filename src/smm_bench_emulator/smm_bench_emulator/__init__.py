"""The bench in a box: the I/O board side of the SMM hardware protocol (docs/HW_PROTOCOL.md)."""
