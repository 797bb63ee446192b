"""The ROS 2 station's compiled per-message path (:class:`~.path.CompiledPath`): Cyclone
DDS's C functions (:mod:`.cyclone`), CDR in compiled code (:mod:`.cdr`), the chain's
update (:mod:`.chain`) and the loop (:mod:`.loop`)."""
