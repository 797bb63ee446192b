"""The compiled per-message paths' shared pieces: what a station does with an ordinary
message once a transport has read it (:mod:`.accept`: the checks, the pairing, the load's
bookkeeping), the chain's update (:mod:`.chain`), and the path's state crossing to and from
the station's Python objects, its start and its summary (:mod:`.path`). The transports'
own parts (reading and writing the messages) are ``ftdrake.hardware.ros2.fast`` (Cyclone
DDS) and ``ftdrake.hardware.lcm.fast`` (liblcm)."""
