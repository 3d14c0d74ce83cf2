"""Interface contract of the SMM stack: topic names, QoS, message <-> numpy conversions."""
