"""The G-code stage: design folder → front, back and combined print programs, printer profiles;
the safety checker of any program (``checker``) and the rigid fit of the back side's registration
marks (``alignment``)."""
