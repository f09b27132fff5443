"""``--foxglove [PORT]``: the ``--viz`` content served live over Foxglove's WebSocket protocol.

The same topics, schemas (``viz_schemas``, JSON schema) and JSON messages as the MCAP file of
``robot.viz``, sent as each window is decided (``VizWriter(..., live=FoxgloveLive(port))``)
through ``foxglove-sdk``'s WebSocket server: Foxglove (app or web) connects to
``ws://HOST:PORT`` and shows the plan, the scans at the anchor, the path, the state and the
alternatives while the robot drives. The plan is sent once per run; a client that subscribes
later gets it again on subscribing.
"""

from __future__ import annotations

import json

__all__ = ["FoxgloveLive", "DEFAULT_PORT"]

DEFAULT_PORT = 8765  # Foxglove's default


class FoxgloveLive:
    """A Foxglove WebSocket server with one channel per viz topic.

    Args:
        port: TCP port (0: any free one; ``port`` then says which).
        host: address to listen on (``127.0.0.1``: this machine only; ``0.0.0.0`` for a
            viewer on another machine).

    Raises:
        OSError: the port cannot be opened (in use, no permission).
    """

    LATCHED = ("/mfcl/plan",)

    def __init__(self, port: int = DEFAULT_PORT, host: str = "127.0.0.1"):
        import foxglove

        from mfcl_jax.robot.viz import TOPICS
        from mfcl_jax.robot.viz_schemas import SCHEMAS

        live = self

        class _Listener(foxglove.ServerListener):
            def on_subscribe(self, client, channel) -> None:
                live._resend(channel.topic)

        self._last: dict[str, tuple[int, bytes]] = {}
        self._channels = {}
        for topic, name in TOPICS.items():
            schema = foxglove.Schema(name=name, encoding="jsonschema",
                                     data=json.dumps(SCHEMAS[name]).encode())  # fmt: skip
            self._channels[topic] = foxglove.Channel(topic, schema=schema,
                                                     message_encoding="json")  # fmt: skip
        try:
            self._server = foxglove.start_server(name="mfcl", host=host, port=int(port),
                                                 server_listener=_Listener())  # fmt: skip
        except Exception as e:  # the SDK raises its own error types
            raise OSError(f"--foxglove: cannot serve on {host}:{port}: {e}") from None
        self.host, self.port = host, int(self._server.port)

    def _resend(self, topic: str) -> None:
        if topic in self._last:
            ns, data = self._last[topic]
            self._channels[topic].log(data, log_time=ns)

    def put(self, topic: str, schema: str, ns: int, data: bytes) -> None:
        """Sends one message (``schema``: its schema's name, fixed per topic)."""
        if topic in self.LATCHED:
            self._last[topic] = (ns, data)
        self._channels[topic].log(data, log_time=ns)

    def close(self) -> None:
        self._server.stop()
