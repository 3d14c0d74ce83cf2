"""The whole SMM graph: its description, ``smm-launch``, the launch files, the scenarios and the demo.

The one package that knows every node.
"""
