"""The ROS 2 station's compiled per-message path (:class:`~.path.CompiledPath`): Cyclone
DDS's C functions (:mod:`.cyclone`), CDR in compiled code (:mod:`.cdr`) and the loop
(:mod:`.loop`); what it shares with the LCM station's is :mod:`ftdrake.hardware.fast`."""
