"""Bauer MO 64 barrier motor control, LogiTed bus over TCP/IP and RS485 (document 003).

So far only the pure codec (:mod:`devices.mo64.codec`): frames, telegram types, answer decoders
and the setting directory. The adapter, twin and page build on it.
"""
