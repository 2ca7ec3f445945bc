"""Torch preview renderer: environment lighting with MIS, AgX, FLIP."""
