"""From a case file to model objects: the case file and its schema, time schedules, meshing, the
mechanics, flow and poromechanics set-up, the in-situ state and the registry of built-in cases."""
