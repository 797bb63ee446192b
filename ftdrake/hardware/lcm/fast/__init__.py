"""The LCM station's compiled per-message path (:class:`~.path.CompiledPath`): liblcm's C
functions and the station's connection over them (:mod:`.liblcm`), the LCM messages in
compiled code (:mod:`.codec`) and the loop (:mod:`.loop`); what it shares with the ROS 2
station's is :mod:`ftdrake.hardware.fast`."""
