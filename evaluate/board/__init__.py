"""The board study on real photographs (and on renders of boards): see ``study.py``; their digital twin: ``twin/``."""
