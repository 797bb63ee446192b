"""Offline tools around the runtime chain: recording its signals as a log (``recorder``)."""
