"""ROS 2 without a ROS installation: the layer as a live node (``mfcl ros2``) and a dataset
played onto topics (``mfcl play``), over DDS (Cyclone DDS from PyPI) with ROS 2's topic and
type names and QoS.

- ``messages``: the ROS 2 message types as DDS types (byte-identical CDR);
- ``dds``: the participant, ``rt/`` topic names, ``ROS_DOMAIN_ID``, QoS profiles;
- ``feed``: scans, odometry and ``/tf_static`` in, ``ScanSequence`` prefixes out;
- ``node``: windows decided, ``/mfcl/status`` and ``/initialpose`` (and ``/tf``) out;
- ``play``: a recording published as a robot publishes it;
- ``run``: what the two commands do with their flags.

Importing this package loads nothing; ``messages`` needs ``cyclonedds``.
"""
