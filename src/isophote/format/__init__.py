"""The file formats: a VectorImage on disk and back.

    limits.py    every limit and magic number of the formats, its reason beside it
    validate.py  the checks the .isoph and SVG readers and writers share
    isoph/       the .isoph binary format (specification: docs/format.md)
    svg/         the isophote SVG profile (specification: its package docstring)
    _coder/      the range coder of .isoph's compression 3, and its plain-Python twin
"""
