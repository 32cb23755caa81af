"""Tests of the G-code the writer produces, read back by an independent reader (`reader.py`)."""
