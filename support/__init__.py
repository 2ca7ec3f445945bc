"""What the tests and the benches both use: running Blender in a child, the installed extension, the
sample-asset paths, small inputs, the agreement cases, the held-out real assets, report provenance and
the sheen measurement, MaterialX's OSL generator on our documents with the Script node that
renders its output, and the preview-ball scene in Cycles.

``tests/`` and ``bench/`` never import each other (``tests/test_layering.py``); both import this
package, which imports the product only.
"""
