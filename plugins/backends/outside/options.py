"""The options of the ``outside`` backend: none (the package registers them)."""

from __future__ import annotations

from safeembodai_core.descriptions import BackendDescription, BackendOptions


class OutsideOptions(BackendOptions):
    """No options: the client is outside."""

    def describe(self) -> BackendDescription:
        return BackendDescription(model="an outside client over rosbridge (who or what it was is not recorded)",
                                  model_source="safeembodai serve-robot: commands received, no prompt sent")
