"""What talking to an MQTT broker can raise, for the three clients of one (app/mqtt.py's publisher,
app/sparkplug.py's edge node and app/site_view.py's read-only view): each catches exactly these around
its connection and lets anything else surface as the bug it is."""

from __future__ import annotations

import aiomqtt

# aiomqtt's own errors; the socket's and TLS's (OSError, ConnectionError among them; a password file that
# cannot be read too); the bounds of our own waits; paho's refusal of a bad host name (ValueError)
BROKER_ERRORS: tuple[type[Exception], ...] = (aiomqtt.MqttError, OSError, TimeoutError, ValueError)
