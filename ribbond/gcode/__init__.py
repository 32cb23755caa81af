"""The G-code stage: design folder → front, back and combined print programs, printer profiles.

Built by issue 5; nothing is here yet.
"""
