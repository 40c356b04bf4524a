"""The browser monitor: a Viser page that draws a running line from the bus and sends controls over it."""
