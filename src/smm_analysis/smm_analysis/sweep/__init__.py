"""``smm-sweep``: gain studies on the batched closed loop (spec, execution, analysis, outputs)."""
