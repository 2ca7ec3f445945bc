"""Everything that imports bpy: operators, panels, Cycles graph builder."""
