"""Host-independent core: material schema, graph, enhancement, exporters."""
