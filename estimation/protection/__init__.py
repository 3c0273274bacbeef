"""Mobility fault protection: the onboard checks that stop a drive (Biesiadecki and Maimone
2006). Flight software: it reads only the rover's own estimate and sensors."""
