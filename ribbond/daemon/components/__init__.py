"""The service's components, one per concern (compiler, printing, aligner, resume, manual control,
tables, calibrations, ...): each given only what it needs by ``ribbond.daemon.service``."""
