"""Tests of the documents: the commands they show, the tables and figures they quote, the guide run top to bottom."""
