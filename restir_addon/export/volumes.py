"""A material's Volume socket as a homogeneous medium (core/integrators/media.py):
absorption and scattering coefficients, emission and anisotropy, as Cycles'
volume closures define them.

- Volume Absorption: sigma_a = (1 - Color) x Density.
- Volume Scatter: sigma_s = Color x Density, anisotropy g (Henyey-Greenstein;
  the other phase functions render as Henyey-Greenstein, with a warning).
- Principled Volume: sigma_s = Color x Density, sigma_a = (1 - Color) x
  (1 - sqrt(Absorption Color)) x Density, emission Emission Strength x Emission
  Color plus the blackbody of the Temperature (core/integrators/grid_media.py's
  blackbody_emission; a volume object's temperature grid scales it).
- Volume Coefficients: its absorption, scattering and emission coefficients.
- Emission: Color x Strength; Add Shader sums, Mix Shader mixes by its factor.

Inputs are read as the constants they hold: an input fed by a link
(a texture, an attribute) gives its own default value instead, with a
warning (heterogeneous media are not rendered). A volume object's grids
are the exception (export/volume_objects.py): there a Principled Volume's
Density Attribute, or an Attribute node feeding a Density, names the grid
that scales the density, its Color Attribute a grid that tints it and its
Temperature Attribute one that drives its blackbody (read with ``grids``).
"""

from collections import namedtuple

import numpy as np

from ...core.integrators.grid_media import blackbody_emission

ZERO = np.zeros(3)


def _source(socket):
    """The output socket feeding ``socket`` through reroutes, or None."""
    seen = 0
    while socket is not None and socket.is_linked and seen < 64:
        link = socket.links[0]
        if not link.is_valid or link.is_muted:
            return None
        node = link.from_node
        if node.type == "REROUTE":
            socket = node.inputs[0]
            seen += 1
            continue
        return link.from_socket
    return None


class _Reader:
    def __init__(self, warn, grids=None, unit_density=False):
        self.warn = warn
        self.unit_density = unit_density    # Density inputs read as 1 (a texture drives them)
        self.grids = grids      # a list: grid names that scale densities are put in it
        # With grids: (temperature grid name, Temperature, Blackbody
        # Intensity, Blackbody Tint) of each Principled Volume's blackbody,
        # left out of the emission for the grid to give it.
        self.blackbody = []
        # With grids: (colour grid name, Color, Density, 1 - sqrt(Absorption
        # Color), Anisotropy) of each Principled Volume with a Color Attribute.
        self.colors = []

    def value(self, node, name, default):
        socket = node.inputs.get(name)
        if socket is None:
            return np.asarray(default, np.float64)
        if self.unit_density and name == "Density":
            return np.asarray(1.0, np.float64)
        if socket.is_linked:
            src = _source(socket)
            if self.grids is not None and name == "Density" and src is not None and src.node.type == "ATTRIBUTE":
                self.grids.append(src.node.attribute_name)
                return np.asarray(1.0, np.float64)
            self.warn(f"volume input '{name}' of node '{node.name}' is linked (a texture or attribute: "
                      "heterogeneous media are not rendered); its own value is used")
        value = getattr(socket, "default_value", default)
        try:
            out = np.asarray(tuple(value), np.float64)[:3]
        except TypeError:
            out = np.asarray(float(value), np.float64)
        return out if np.isfinite(out).all() else np.asarray(default, np.float64)

    def color(self, node, name, default=(0.8, 0.8, 0.8)):
        v = self.value(node, name, default)
        return np.broadcast_to(v, (3,)).astype(np.float64) if v.ndim == 0 else v[:3]

    def number(self, node, name, default):
        v = self.value(node, name, default)
        return float(v if v.ndim == 0 else v.mean())

    def closure(self, socket, depth=0):
        """(sigma_a, sigma_s, emission, sigma_s-weighted g sum) of what feeds socket."""
        out = _source(socket)
        if out is None or depth > 32:
            return ZERO, ZERO, ZERO, 0.0
        node = out.node
        kind = node.type
        if kind == "VOLUME_ABSORPTION":
            density = max(self.number(node, "Density", 1.0), 0.0)
            return np.clip(1.0 - self.color(node, "Color"), 0, None) * density, ZERO, ZERO, 0.0
        if kind in ("VOLUME_SCATTER", "VOLUME_COEFFICIENTS"):
            phase = getattr(node, "phase", "HENYEY_GREENSTEIN")
            if phase != "HENYEY_GREENSTEIN":
                self.warn(f"node '{node.name}': phase function {phase} renders as Henyey-Greenstein")
            g = float(np.clip(self.number(node, "Anisotropy", 0.0), -0.999, 0.999))
            if kind == "VOLUME_COEFFICIENTS":
                sa = np.clip(self.color(node, "Absorption Coefficients", (1, 1, 1)), 0, None)
                ss = np.clip(self.color(node, "Scatter Coefficients", (1, 1, 1)), 0, None)
                em = np.clip(self.color(node, "Emission Coefficients", (0, 0, 0)), 0, None)
                return sa, ss, em, float(ss.mean() * g)
            density = max(self.number(node, "Density", 1.0), 0.0)
            ss = np.clip(self.color(node, "Color"), 0, None) * density
            return ZERO, ss, ZERO, float(ss.mean() * g)
        if kind == "PRINCIPLED_VOLUME":
            density = max(self.number(node, "Density", 1.0), 0.0)
            attribute = node.inputs.get("Density Attribute")
            if self.grids is not None and attribute is not None and getattr(attribute, "default_value", ""):
                self.grids.append(str(attribute.default_value))
            color = np.clip(self.color(node, "Color", (0.5, 0.5, 0.5)), 0, None)
            absorb = np.clip(self.color(node, "Absorption Color", (0, 0, 0)), 0, None)
            g = float(np.clip(self.number(node, "Anisotropy", 0.0), -0.999, 0.999))
            colour = node.inputs.get("Color Attribute")
            if self.grids is not None and colour is not None and getattr(colour, "default_value", ""):
                self.colors.append((str(colour.default_value), tuple(float(x) for x in color), density,
                                    tuple(float(x) for x in np.clip(1.0 - np.sqrt(absorb), 0, None)), g))
            ss = color * density
            # (Cycles takes the square root of the Absorption Color.)
            sa = np.clip(1.0 - color, 0, None) * np.clip(1.0 - np.sqrt(absorb), 0, None) * density
            em = max(self.number(node, "Emission Strength", 0.0), 0.0) * np.clip(
                self.color(node, "Emission Color", (1, 1, 1)), 0, None)
            intensity = self.number(node, "Blackbody Intensity", 0.0)
            if intensity > 1e-3:
                kelvin = max(self.number(node, "Temperature", 1000.0), 0.0)
                tint = np.clip(self.color(node, "Blackbody Tint", (1.0, 1.0, 1.0)), 0, None)
                attribute = node.inputs.get("Temperature Attribute")
                name = str(getattr(attribute, "default_value", "") or "")
                if self.grids is not None and name:
                    self.blackbody.append((name, kelvin, float(intensity), tuple(float(x) for x in tint)))
                else:
                    em = em + blackbody_emission(kelvin, intensity) * tint
            return sa, ss, em, float(ss.mean() * g)
        if kind == "EMISSION":
            strength = max(self.number(node, "Strength", 1.0), 0.0)
            return ZERO, ZERO, np.clip(self.color(node, "Color", (1, 1, 1)), 0, None) * strength, 0.0
        if kind == "ADD_SHADER":
            a, b = (self.closure(s, depth + 1) for s in node.inputs[:2])
            return tuple(x + y for x, y in zip(a, b))
        if kind == "MIX_SHADER":
            fac = float(np.clip(self.number(node, "Fac", 0.5), 0, 1))
            a, b = self.closure(node.inputs[1], depth + 1), self.closure(node.inputs[2], depth + 1)
            return tuple((1 - fac) * x + fac * y for x, y in zip(a, b))
        self.warn(f"node '{node.name}' ({kind}) in the volume is not supported; it adds no medium")
        return ZERO, ZERO, ZERO, 0.0


def _medium(sa, ss, em, gs):
    g = gs / ss.mean() if ss.mean() > 0 else 0.0
    return {"sigma_a": tuple(float(x) for x in sa), "sigma_s": tuple(float(x) for x in ss),
            "emission": tuple(float(x) for x in em), "g": float(np.clip(g, -0.999, 0.999))}


def textured_density(socket):
    """The Density input of the one volume node feeding a Volume socket when
    nodes other than an Attribute drive it (a texture, math), else None."""
    out = _source(socket)
    if out is None or out.node.type not in ("PRINCIPLED_VOLUME", "VOLUME_SCATTER", "VOLUME_ABSORPTION"):
        return None
    density = out.node.inputs.get("Density")
    src = _source(density) if density is not None else None
    if src is None or src.node.type == "ATTRIBUTE":
        return None
    return density


def read_volume(socket, warn, unit_density=False):
    """The medium dict of a Volume socket (core/integrators/media.py), or None if it
    gives none. unit_density: per unit of a density a texture gives."""
    sa, ss, em, gs = _Reader(warn, unit_density=unit_density).closure(socket)
    if not (np.max(sa) > 0 or np.max(ss) > 0 or np.max(em) > 0):
        return None
    return _medium(sa, ss, em, gs)


GridShader = namedtuple("GridShader", "scaled constant names blackbody colors")


def read_grid_volume(socket, warn):
    """A volume object's shader, a GridShader: the medium dict of absorption
    and scattering per unit of the grid, the medium dict of emission, the
    names of the grids that scale the density, and _Reader's blackbodies and
    colour grids. Without a grid name the whole medium is constant inside
    the volume (the second dict holds it all), as Cycles fills a volume
    object's bounds when no grid drives the density."""
    grids = []
    reader = _Reader(warn, grids)
    sa, ss, em, gs = reader.closure(socket)
    if grids:
        return GridShader(_medium(sa, ss, ZERO, gs), _medium(ZERO, ZERO, em, 0.0), grids, reader.blackbody,
                          reader.colors)
    return GridShader(_medium(ZERO, ZERO, ZERO, 0.0), _medium(sa, ss, em, gs), grids, reader.blackbody,
                      reader.colors)
