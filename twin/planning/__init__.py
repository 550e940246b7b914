"""Sites from the maps users have, and the plan of a campaign on them.

- :mod:`.floor_map`: :class:`FloorMap`, the free floor and the obstacles of a site in the
  map's frame (shapely geometry), and :class:`MapError`.
- :mod:`.maps`: reading a ROS occupancy grid, a DXF floor plan or a building mesh into a
  :class:`FloorMap`.
- :mod:`.route`, :mod:`.tour`, :mod:`.stations`: shortest paths with clearance, the order
  of the visits, where the parent stands for each camera.
"""
