"""Out to the tools users run: auvsim's data in other programs' formats and on their
interfaces.

``ros2`` writes a mission as a ROS 2 bag in MCAP (``auvsim export --to mcap``), with
``rosmsg`` (the message definitions it embeds), ``cdr`` (their fixed-layout CDR encoding,
vectorised) and ``mcapfile`` (the chunks); ``a50`` plays a mission as a Water Linked DVL
A50 on TCP (``auvsim serve``). PD0, a file format the importer reads too, is
``auvsim.data.pd0``.
"""
