"""Uploads validated against a rover: what the validator needs to know of it (``context``)
and the worker processes that validate off the server's interpreter (``pool``)."""
