"""Out to the tools users run: auvsim's datasets in other programs' formats.

``ros2`` writes a mission as a ROS 2 bag in MCAP (``auvsim export --to mcap``), with
``rosmsg`` (the message definitions it embeds) and ``cdr`` (their fixed-layout CDR
encoding, vectorised).
"""
