"""The digital twin's plumbing: a simulated arm behind the interfaces a real one has (an STS servo bus on a
serial port), so that an unmodified driver talks to it."""
