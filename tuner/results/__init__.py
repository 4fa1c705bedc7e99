"""Results for people: the HTML report of one fit (``report``) and of a fleet (``fleet_summary``).
"""
