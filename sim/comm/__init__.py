"""The communication link between the ground and a rover: the plan, its windows, the
onboard store and the link that carries commands and data across the light time.

``plan`` holds the operators' communication plan (``CommPlan``: when the high-gain antenna
session is, at what rates, the relay orbiter's mask, the store's size, the planning
deadline); ``windows`` predicts when each link is up, as the ground does from published
ephemerides (the relay orbiter's orbit, Earth from DE421); ``store`` is the rover's onboard
store (products by priority, overflow told as gaps); ``link`` carries uplinks and products
across the light time (what is sent when, and when it arrives).
"""
