"""A record's two outward forms, outside the numerical core: the JSON codec of the calf record
(its schema, parsed and validated once) and the mesh writers (STL, GLB, glTF) of its surface.
"""
