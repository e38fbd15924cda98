"""Montezuma's Revenge, Room 1: the critical positions (Figure 4.2) and the scripted expert."""
