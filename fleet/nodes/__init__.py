"""The OS processes of a running line, one module each: sim server, arm controller, coordinator, monitor, recorder, env
arm; thin: decode, call a library, publish."""
