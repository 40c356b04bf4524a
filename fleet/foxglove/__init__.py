"""The line served to the Foxglove app over its own WebSocket protocol (`foxglove.websocket.v1`, by foxglove-sdk)."""
