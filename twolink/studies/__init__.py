"""Studies: each measures (returns data) in one module and presents (tables, figures,
Markdown) in another.
"""
