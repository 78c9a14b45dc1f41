"""SafeEmbodAI's built-in plugins (imported as ``safeembodai_plugins``).

Each subpackage is an ordinary plugin, declared as an entry point of the ``safeembodai`` group
exactly as a third-party package would declare its own. Plugin modules stay light: heavy
libraries (pybullet, litellm, cv2) are imported inside component factories.
"""
