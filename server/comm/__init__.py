"""Operating across light time: a rover's communication mode, its link as the runtime hosts
it (``hosting``, ``mission``), and what the ground serves of it."""
