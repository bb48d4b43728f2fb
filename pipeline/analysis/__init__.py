"""The analysis of a case: the pilot, one mesh level (mesh -> loads -> solve -> peaks), the meshes of an answer."""
