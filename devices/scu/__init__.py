"""Ewellix (Schaeffler) SCU actuator control unit on RS232 (document 002): remote session,
data directory, functions. ``codec`` (telegrams, CRC, stream splitter, directories) and
``params`` (the data directory with typed values) are pure; no device type is registered yet."""
