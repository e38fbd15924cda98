"""The graph live in Foxglove (the Foxglove WebSocket protocol, served by foxglove-sdk)."""
