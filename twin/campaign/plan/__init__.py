"""The geometry of the campaign's decisions, on the map: one idea per module.

- :mod:`.route`: :class:`RoutePath`, the reference route walked by arc length.
- :mod:`.legs`: the parent's stations along it, in equal CPS legs.
- :mod:`.formation`: where the two children stop during a leg.
- :mod:`.view_stops`: where a child stops in a camera's view, and the tour of those stops.
- :mod:`.clearance`: where a robot fits, which segments are clear, the robots' profiles.
- :mod:`.occlusion`: prisms hidden by their own assembly, and the heading that shows them.
- :mod:`.stop`: :class:`Stop`, a planned stop of a robot.

Strategies (:mod:`twin.campaign.strategy`) decide with these; the campaign executes.
Nothing here measures, and nothing here reads the twin's simulated noise: the instrument's
range comes from the interface.
"""
