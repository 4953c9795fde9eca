"""auvsim's data in the formats and on the interfaces other tools read: ``a50`` plays a
mission as a Water Linked DVL A50 on TCP (``auvsim serve``)."""
