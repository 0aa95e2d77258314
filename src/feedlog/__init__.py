"""feedlog: record, align, simulate and learn how CNC machine tools really move."""

__version__ = "0.1.0"
