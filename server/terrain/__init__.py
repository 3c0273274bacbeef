"""The ground's own knowledge of the terrain: its map (an orbital DEM refined by the rover's
stereo pairs), and the advice it gives drivers from that map."""
