"""Bag I/O of pac runs, used by the rig (recorder, simulate, replay) and the analysis alike.

Modules, one job each: ``typestore`` (ROS 2 Jazzy + pac_interfaces types from the .msg files),
``names`` (topic names in bags), ``qos`` (QoS profiles as rosbag2 records them), ``cdr`` (whole
runs of messages as CDR with numpy), ``mcap_writer`` (chunked, indexed MCAP), ``writer``
(``BagWriter``: rosbag2 v9 directories), ``mcap_reader`` (every intact message of an MCAP file,
one line per damage), ``metadata`` (what metadata.yaml declares), ``recovery`` (every intact
message of a bag: what every reader reads), ``reader`` (``read_bag`` into columns).
"""
