"""Plugins: which are loaded (``manager``), what they register by name (``registry``), how a scenario
names one (``refs``) and the one place a component's factory is called (``building``)."""
