"""Render Properties panels."""


def register():
    pass


def unregister():
    pass
