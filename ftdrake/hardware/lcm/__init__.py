"""The LCM station's compiled per-message path (:mod:`.fast`). The station itself, its
messages and its Python transport are :mod:`ftdrake.hardware.station`,
:mod:`ftdrake.hardware.messages` and :mod:`ftdrake.hardware.transport`."""
