"""Browser tests of the images the rover sends down (the timeline's Images lane, the pair's
dialog); a folder of their own (tests/browser holds its 15 modules)."""
