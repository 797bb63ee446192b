"""Fitted compensators as files: the model file (saved and loaded without running code from
it) and the ONNX export."""
