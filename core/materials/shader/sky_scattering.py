"""The atmosphere of Blender's Single and Multiple Scattering skies, as tables.

Cycles does not evaluate these skies per ray: it precomputes a 512 x 256
table of CIE XYZ radiance over (azimuth from the sun, elevation) once per
parameter set and reads it bilinearly (core/materials/shader/sky.py). Here are the two
tables and the sun's radiance at the bottom and top of its disc, computed
as Blender's sky library does so the renders agree with Cycles':

- Rows: texel row y of H has elevation sign(l) l^2 pi/2 with l = 2 (y + 0.5) / H - 1
  (multiple) or l = y / (H / 2) - 1 (single: only the upper half is filled,
  the ground is black), so texels crowd at the horizon. Columns: azimuth
  2 pi (x + 0.5) / W (multiple) or 2 pi x / W - pi (single), the sun at u = 0.5;
  the right half mirrors the left.
- Multiple Scattering (Fernando Garcia Linan's model, Blender 5's default):
  4 wavelengths (630, 560, 490, 430 nm), altitudes in km, an Earth of radius
  6371 km under a 100 km atmosphere of molecules (Rayleigh), ozone and
  aerosols (a phase function of g = 0.8). Radiance is marched along the view
  ray in 64 steps with the energy-conserving step integral of Hillaire
  (2016); light reaching each step is the sun's through a transmittance table
  (256 sun cosines x 64 altitudes, 64 steps each) plus an analytic fit of
  higher orders and the ground's second bounce (albedo 0.3).
- Single Scattering (Nishita 1993, Blender 2.90's sky): 21 wavelengths
  380-780 nm, metres, Earth 6360 km, atmosphere 6420 km, Rayleigh and Mie
  (g = 0.76) densities falling exponentially (8 km, 1.2 km), ozone as a tent
  about 25 km; 32 steps along the view ray and an 8-node Gauss-Laguerre
  quadrature of the optical depth toward the sun.

Everything is vectorised over the texels (float64: the tables are small and
the geometry needs the precision, a planet's radius against metres).
"""

import numpy as np

WIDTH, HEIGHT = 512, 256

# --- Multiple scattering (kilometres) ------------------------------------------------------------

_R = 6371.0
_THICK = 100.0
_RA = _R + _THICK
_T_STEPS = 64
_S_STEPS = 64
_TX, _TY = 256, 64
_SUN = np.array([1.679, 1.828, 1.986, 1.307])
_MOL = np.array([6.605e-3, 1.067e-2, 1.842e-2, 3.156e-2])
_OZONE = np.array([3.472e-25, 3.914e-25, 1.349e-25, 11.03e-27]) * 334.5 * 3.78547397e20
_AER_ABS = np.array([2.8722e-24, 4.6168e-24, 7.9706e-24, 1.3578e-23])
_AER_SCA = np.array([1.5908e-22, 1.7711e-22, 2.0942e-22, 2.4033e-22])
_AER_BASE, _AER_BACK, _AER_H = 1.3681e20, 2e6, 0.73
_G = 0.8
_MS_FIT = 0.02 * np.array([0.217, 0.347, 0.594, 1.0])
_MS_XYZ = np.array([[53.386917738564668, 22.981337506691025, 0.0],
                    [43.904844466369358, 71.347795700053394, 0.102506867965741],
                    [1.6137278251608962, 18.422960591455485, 31.742921188390806],
                    [20.762668673810577, 2.3614213523314369, 110.48009643252140]])


def _sphere_hit(oz, dz, radius):
    """Distance along unit dir d from (0, 0, oz) to the sphere of `radius` about
    the origin, as Blender's sky library picks it (the far hit from inside, the
    near one from outside, -1 for none). dz: the direction's z."""
    b = oz * dz
    c = oz * oz - radius * radius
    d = b * b - c
    root = np.sqrt(np.maximum(d, 0.0))
    t = np.where(d >= b * b, -b + root, -b - root)
    return np.where(((c > 0) & (b > 0)) | (d < 0), -1.0, t)


def _ms_coefficients(h, density):
    """(extinction, molecular scattering, aerosol scattering) (..., 4) at altitudes h (km)."""
    air, aerosol, ozone = density
    aer = (_AER_BASE * aerosol) * (np.exp(-h / _AER_H) + _AER_BACK / _AER_BASE)
    log_h = np.log(np.maximum(h, 1e-4))
    ozone_f = ozone * np.exp(-(log_h - 3.22261) ** 2 * 5.55555555 - log_h)
    air_f = air * np.exp(-0.07771971 * np.power(h, 1.16364243))
    f32 = np.float32
    aer, ozone_f, air_f = (x.astype(f32)[..., None] for x in (aer, ozone_f, air_f))
    mol_sca = _MOL.astype(f32) * air_f
    aer_sca = _AER_SCA.astype(f32) * aer
    return (_AER_ABS + _AER_SCA).astype(f32) * aer + _OZONE.astype(f32) * ozone_f + mol_sca, mol_sca, aer_sca


def _ms_transmittance(cos_theta, norm_alt, density):
    """Transmittance (..., 4) toward a sun at zenith cosine cos_theta from normalised altitudes."""
    cos_theta, norm_alt = np.broadcast_arrays(np.asarray(cos_theta, np.float64),
                                              np.asarray(norm_alt, np.float64))
    oz = _R + norm_alt * _THICK
    sx, sz = -np.sqrt(np.maximum(1.0 - cos_theta ** 2, 0.0)), cos_theta
    dt = _sphere_hit(oz, sz, _RA) / _T_STEPS
    t = (np.arange(_T_STEPS) + 0.5)[:, None] * dt.ravel()[None, :]          # (steps, n)
    px, pz = sx.ravel() * t, oz.ravel() + sz.ravel() * t
    alt = np.maximum(np.sqrt(px * px + pz * pz) - _R, 0.0)
    ext, _, _ = _ms_coefficients(alt, density)
    depth = ext.sum(axis=0) * dt.ravel()[:, None]
    return np.exp(-depth).reshape(cos_theta.shape + (4,))


class _Transmittance:
    """The 256 x 64 transmittance table and its bilinear lookups."""

    def __init__(self, density):
        u = np.arange(_TX) / (_TX - 1)
        v = np.arange(_TY) / (_TY - 1)
        self.lut = _ms_transmittance((u * 2 - 1)[None, :], v[:, None], density)   # (TY, TX, 4)
        self.flat = self.lut.reshape(-1, 4).astype(np.float32)
        self.up = self.lut[:, _TX - 1]

    def lookups(self, cos_theta, norm_alt):
        """(transmittance toward the sun, the same from the ground) at zenith
        cosines cos_theta from normalised altitudes: two bilinear lookups that
        share their columns."""
        x = np.clip(cos_theta * 0.5 + 0.5, 0, 1) * (_TX - 1)
        y = np.clip(norm_alt, 0, 1) * (_TY - 1)
        x1, y1 = x.astype(np.int64), y.astype(np.int64)
        x2, y2 = np.minimum(x1 + 1, _TX - 1), np.minimum(y1 + 1, _TY - 1)
        fx, fy = (x - x1).astype(np.float32)[:, None], (y - y1).astype(np.float32)[:, None]
        flat = self.flat
        a, b = np.take(flat, y1 * _TX + x1, axis=0), np.take(flat, y1 * _TX + x2, axis=0)
        c, d = np.take(flat, y2 * _TX + x1, axis=0), np.take(flat, y2 * _TX + x2, axis=0)
        bottom = a + fx * (b - a)
        at = bottom + fy * (c + fx * (d - c) - bottom)
        g1, g2 = np.take(flat, x1, axis=0), np.take(flat, x2, axis=0)
        return at, g1 + fx * (g2 - g1)

    def to_sun(self, norm_alt):
        """Transmittance straight up (cos 1) from normalised altitudes."""
        y = np.clip(norm_alt, 0, 1) * (_TY - 1)
        y1 = y.astype(np.int64)
        y2 = np.minimum(y1 + 1, _TY - 1)
        fy = (y - y1)[..., None]
        return self.up[y1] + fy * (self.up[y2] - self.up[y1])


def _multiscattering(trans, to_ground, cos_theta, norm_alt, dist):
    """Light reaching a point beyond the sun's single scattering: the fit of
    higher orders and the ground's bounce (Blender's lookup_multiscattering)."""
    omega = 2 * np.pi * (1.0 - np.sqrt(np.maximum(1.0 - (_R / dist) ** 2, 0.0)))
    ground_to_sample = (trans.up[0] / trans.to_sun(norm_alt)).astype(np.float32)
    c = cos_theta[:, None]
    ground = ((0.3 / (4 * np.pi * np.pi)) * omega * cos_theta).astype(np.float32)[:, None] \
        * to_ground * ground_to_sample
    return (_MS_FIT / (1.0 + 5.0 * np.exp(-17.92 * c))).astype(np.float32) + ground


def multiple_scattering_table(sun_elevation, altitude, air, aerosol, ozone):
    """(HEIGHT, WIDTH, 3) XYZ radiance of the Multiple Scattering sky (altitude in metres)."""
    density = (air, aerosol, ozone)
    trans = _Transmittance(density)
    alt = np.clip(altitude, 1.0, 99999.0) / 1000.0
    cz = np.cos(np.pi / 2 - sun_elevation)
    sun = np.array([-np.sqrt(max(1 - cz * cz, 0.0)), 0.0, cz])
    half = WIDTH // 2
    az = 2 * np.pi * (np.arange(half) + 0.5) / WIDTH
    lv = (np.arange(HEIGHT) + 0.5) / HEIGHT * 2 - 1
    el = np.sign(lv) * lv * lv * np.pi / 2
    d = np.stack(np.broadcast_arrays(np.cos(el)[:, None] * np.cos(az)[None, :],
                                     np.cos(el)[:, None] * np.sin(az)[None, :],
                                     np.sin(el)[:, None]), axis=-1).reshape(-1, 3)
    oz = _R + alt
    t_atm, t_ground = _sphere_hit(oz, d[:, 2], _RA), _sphere_hit(oz, d[:, 2], _R)
    t_d = np.where(t_ground < 0, t_atm, t_ground)
    mu = -(d @ sun)
    mol_phase = (3 / (16 * np.pi)) * (1 + mu * mu)
    den = 1 + _G * _G + 2 * _G * mu
    aer_phase = (1 / (4 * np.pi)) * (1 - _G * _G) / (den * np.sqrt(den))
    dt = t_d / _S_STEPS
    light = np.zeros((len(d), 4), np.float32)
    transmittance = np.ones((len(d), 4), np.float32)
    mol_phase, aer_phase = (x.astype(np.float32)[:, None] for x in (mol_phase, aer_phase))
    sun_irr = _SUN.astype(np.float32)
    dt32 = dt.astype(np.float32)[:, None]
    for i in range(_S_STEPS):        # steps along every ray at once
        t = (i + 0.5) * dt
        p = d * t[:, None]
        p[:, 2] += oz
        r = np.sqrt((p * p).sum(axis=1))
        h = np.maximum(r - _R, 0.0)
        na = h / _THICK
        cos_sun = (p @ sun) / r
        ext, mol_sca, aer_sca = _ms_coefficients(h, density)
        to_sun, to_ground = trans.lookups(cos_sun, na)
        ms = _multiscattering(trans, to_ground, cos_sun, na, r)
        s = sun_irr * (mol_sca * (mol_phase * to_sun + ms) + aer_sca * (aer_phase * to_sun + ms))
        step = np.exp(-dt32 * ext)
        light += transmittance * (s - s * step) / np.maximum(ext, 1e-7)
        transmittance *= step
    xyz = (light.astype(np.float64) @ _MS_XYZ).reshape(HEIGHT, half, 3)
    return np.concatenate([xyz, xyz[:, ::-1]], axis=1)


def multiple_scattering_sun(sun_elevation, angular_diameter, altitude, air, aerosol, ozone):
    """XYZ radiance (2, 3) at the bottom and top of the sun's disc."""
    alt = np.clip(altitude, 1.0, 99999.0) / 1000.0
    half = angular_diameter / 2
    solid = 2 * np.pi * (1 - np.cos(half))
    elev = np.array([sun_elevation - half, sun_elevation + half])
    t = _ms_transmittance(np.cos(np.pi / 2 - elev), np.full(2, alt / _THICK), (air, aerosol, ozone))
    return (_SUN * t / solid) @ _MS_XYZ


def earth_intersection_angle(altitude):
    """Angle below the horizon at which the Earth's surface is seen from `altitude` metres."""
    return np.pi / 2 - np.arcsin(_R / (_R + altitude / 1000.0))


# --- Single scattering (metres) -------------------------------------------------------------------

_SR, _SRA = 6360e3, 6420e3
_RAY_H, _MIE_H, _MIE, _MIE_G = 8e3, 1.2e3, 2e-5, 0.76
_S_STEPS1 = 32
_LAMBDA_STEP = 20.0
_IRR = np.array([1.45756829855592995, 1.56596305559738380, 1.65148449067670455, 1.71496242737209315,
                 1.75797983805020541, 1.78256407885924539, 1.79095108475838560, 1.78541550133410665,
                 1.76815554864306845, 1.74122069647250410, 1.70647127164943679, 1.66556087452739887,
                 1.61993437242451854, 1.57083597368892081, 1.51932335059305479, 1.46628494965214395,
                 1.41245852740172451, 1.35844961970384093, 1.30474913844739282, 1.25174963272610817,
                 1.19975998755420621])
_RAY = np.array([5.424820087636473e-5, 4.418549866505454e-5, 3.635151910165377e-5, 3.017929012024763e-5,
                 2.526320226989157e-5, 2.130859310621843e-5, 1.809838025320633e-5, 1.547057129129042e-5,
                 1.330284977336850e-5, 1.150184784075764e-5, 9.99557429990163e-6, 8.72799973630707e-6,
                 7.65513700977967e-6, 6.74217203751443e-6, 5.96134125832052e-6, 5.29034598065810e-6,
                 4.71115687557433e-6, 4.20910481110487e-6, 3.77218381260133e-6, 3.39051255477280e-6,
                 3.05591531679811e-6])
_OZ = np.array([3.25126849861e-9, 5.85395365047e-9, 1.977191155085e-8, 7.309568762914e-8,
                2.0084561514287e-7, 4.0383958096161e-7, 6.3551335912363e-7, 9.6707041180970e-7,
                1.54797400424410e-6, 2.09038647223331e-6, 2.46128056164565e-6, 2.73551299461512e-6,
                2.15125863128643e-6, 1.59051840791988e-6, 1.12356197979857e-6, 7.3527551487574e-7,
                4.6450130357806e-7, 3.3096079921048e-7, 2.2512612292678e-7, 1.4879129266490e-7,
                1.6828623364192e-7])
# CIE 1931 colour matching functions at 380, 400, ... 780 nm.
_CMF = np.array([[0.001368, 0.000039, 0.006450001], [0.01431, 0.000396, 0.06785001],
                 [0.13438, 0.004, 0.6456], [0.34828, 0.023, 1.74706], [0.2908, 0.06, 1.6692],
                 [0.09564, 0.13902, 0.8129501], [0.0049, 0.323, 0.272], [0.06327, 0.71, 0.07824999],
                 [0.2904, 0.954, 0.0203], [0.5945, 0.995, 0.0039], [0.9163, 0.87, 0.001650001],
                 [1.0622, 0.631, 0.0008], [0.8544499, 0.381, 0.00019], [0.4479, 0.175, 0.00002],
                 [0.1649, 0.061, 0.0], [0.04677, 0.017, 0.0], [0.01135916, 0.004102, 0.0],
                 [0.002899327, 0.001047, 0.0], [0.0006900786, 0.0002492, 0.0],
                 [0.0001661505, 0.00006, 0.0], [0.00004150994, 0.00001499, 0.0]])
# Gauss-Laguerre (8 nodes) scaled to end inside the atmosphere, exp(x) folded into the weights.
_QN = np.array([0.006811185292, 0.03614807107, 0.09004346519, 0.1706680068, 0.2818362161,
                0.4303406404, 0.6296271457, 0.9145252695])
_QW = np.array([0.01750893642, 0.04135477391, 0.06678839063, 0.09507698807, 0.1283416365,
                0.1707430204, 0.2327233347, 0.3562490486])


def _densities(h):
    """(..., 3) relative densities of air, aerosols and ozone at heights h (m)."""
    return np.stack([np.exp(-h / _RAY_H), np.exp(-h / _MIE_H),
                     np.maximum(0.0, 1.0 - np.abs(h - 25000.0) / 15000.0)], axis=-1)


def _to_atmosphere(p, d):
    """Distance from points p (..., 3) along unit d (..., 3) out of the atmosphere."""
    b = 2 * (p * d).sum(axis=-1)
    c = (p * p).sum(axis=-1) - _SRA * _SRA
    return (-b + np.sqrt(np.maximum(b * b - 4 * c, 0.0))) / 2


def _optical_depth(p, d):
    """(..., 3) optical depth factors (air, aerosols, ozone) from p along d out of the atmosphere."""
    length = _to_atmosphere(p, d)
    depth = 0.0
    for node_, weight in zip(_QN, _QW):
        q = p + (node_ * length)[..., None] * d
        depth = depth + _densities(np.sqrt((q * q).sum(axis=-1)) - _SR) * weight
    return depth * length[..., None]


def single_scattering_table(sun_elevation, altitude, air, aerosol, ozone):
    """(HEIGHT, WIDTH, 3) XYZ radiance of the Single Scattering sky (altitude in metres)."""
    alt = np.clip(altitude, 1.0, 59999.0)
    scale = np.array([air, aerosol, ozone])
    half_w, half_h = WIDTH // 2, HEIGHT // 2
    rows = np.arange(half_h + 1, HEIGHT)
    lat = np.pi / 2 * (rows / half_h - 1.0) ** 2
    lon = 2 * np.pi / WIDTH * np.arange(half_w) - np.pi
    d = np.stack(np.broadcast_arrays(np.cos(lat)[:, None] * np.cos(lon)[None, :],
                                     np.cos(lat)[:, None] * np.sin(lon)[None, :],
                                     np.sin(lat)[:, None]), axis=-1).reshape(-1, 3)
    sun = np.array([np.cos(sun_elevation), 0.0, np.sin(sun_elevation)])
    origin = np.array([0.0, 0.0, _SR + alt])
    seg = _to_atmosphere(origin[None, :], d) / _S_STEPS1
    mu = d @ sun
    g2 = _MIE_G * _MIE_G
    phase_r = (0.1875 / np.pi) * (1 + mu * mu)
    phase_m = 3 * (1 - g2) * (1 + mu * mu) / (8 * np.pi * (2 + g2) * (1 + g2 - 2 * _MIE_G * mu) ** 1.5)
    depth = np.zeros((len(d), 3))
    spectrum = np.zeros((len(d), len(_IRR)))
    sun_rows = np.broadcast_to(sun, d.shape)
    for i in range(_S_STEPS1):
        p = origin + ((i + 0.5) * seg)[:, None] * d
        dens = scale * _densities(np.sqrt((p * p).sum(axis=1)) - _SR)
        depth += seg[:, None] * dens
        # The Earth's shadow: a sun below the local horizon whose ray meets the ground.
        b = 2 * (p @ sun)
        shadow = (sun[2] < 0) & (b * b - 4 * ((p * p).sum(axis=1) - _SR * _SR) >= 0)
        total = depth + scale * _optical_depth(p, sun_rows)
        att = np.exp(-(total[:, :1] * _RAY + total[:, 1:2] * (1.11 * _MIE) + total[:, 2:] * _OZ))
        sca = (phase_r * dens[:, 0])[:, None] * _RAY + (phase_m * dens[:, 1] * _MIE)[:, None]
        spectrum += np.where(shadow[:, None], 0.0, att * sca * _IRR * seg[:, None])
    xyz = (spectrum @ _CMF * _LAMBDA_STEP).reshape(len(rows), half_w, 3)
    table = np.zeros((HEIGHT, WIDTH, 3))
    table[rows] = np.concatenate([xyz, xyz[:, ::-1]], axis=1)
    return table


def single_scattering_sun(sun_elevation, angular_diameter, altitude, air, aerosol):
    """XYZ radiance (2, 3) at the bottom and top of the sun's disc (black below the horizon)."""
    alt = np.clip(altitude, 1.0, 59999.0)
    half = angular_diameter / 2
    solid = 2 * np.pi * (1 - np.cos(half))
    elev = np.maximum(np.array([sun_elevation - half, sun_elevation + half]), 0.0)
    if elev[1] <= 0:
        return np.zeros((2, 3))
    d = np.stack([np.cos(elev), np.zeros(2), np.sin(elev)], axis=1)
    depth = _optical_depth(np.array([[0.0, 0.0, _SR + alt]] * 2), d)
    tau = _RAY * (depth[:, :1] * air) + 1.11 * _MIE * (depth[:, 1:2] * aerosol)
    return (_IRR * np.exp(-tau) / solid) @ _CMF * _LAMBDA_STEP
