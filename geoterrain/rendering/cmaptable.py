"""Colour maps without matplotlib: the maps this project names, as tables.

``--cmap`` takes any matplotlib colour map; the ones the project names (its help and
docs: terrain, viridis, cividis, gist_earth, Greys_r) are held here as their 256
colours (float32 RGB, base64), computed once from matplotlib by
``python -m geoterrain.rendering.cmaptable`` (which prints this module's table), so
shading with them does not import matplotlib (about 0.2 s of a fresh process).
:func:`colours` looks a height fraction up as matplotlib's ``Colormap.__call__`` does
(``tests/rendering/test_cmaptable.py`` compares both, and the table with matplotlib's
maps, value for value).

Examples
--------
>>> rgb = colours("viridis", np.array([0.0, 0.5, 1.0]))
>>> rgb.shape, bool(rgb[0, 2] > rgb[0, 1])  # viridis starts purple
((3, 3), True)
>>> colours("no-such-map", np.zeros(1)) is None
True
"""

from __future__ import annotations

import base64
import sys

import numpy as np

N = 256
#: the maps' 256 colours: float32 RGB rows, base64 (computed by main())
TABLE = {
    'terrain': (
        'zcxMPs3MTD6amRk/HXJHPi2CVz7yRhw/bRdCPo03Yj5K9B4/vbw8Pu3sbD6ioSE/DWI3Pk2idz76TiQ/XQcy'
        'PtcrgT5S/CY/rawsPoeGhj6qqSk//VEnPjfhiz4CVyw/TfchPuc7kT5aBC8/nZwcPpeWlj6ysTE/7UEXPkfx'
        'mz4KXzQ/PecRPvdLoT5iDDc/jYwMPqempj66uTk/3TEHPlcBrD4SZzw/LdcBPgdcsT5qFD8/+fj4Pbe2tj7C'
        'wUE/mUPuPWcRvD4ab0Q/OY7jPRdswT5yHEc/2djYPcfGxj7KyUk/eSPOPXchzD4id0w/GW7DPSd80T56JE8/'
        'ubi4PdfW1j7S0VE/WQOuPYcx3D4qf1Q/+U2jPTeM4T6CLFc/mZiYPefm5j7a2Vk/OeONPZdB7D4yh1w/2S2D'
        'PUec8T6KNF8/8fBwPff29j7i4WE/MYZbPadR/D46j2Q/cRtGPSzWAD+SPGc/sbAwPYSDAz/q6Wk/8UUbPdww'
        'Bj9Cl2w/MdsFPTTeCD+aRG8/4eDgPIyLCz/y8XE/YQu2POQ4Dj9Kn3Q/4TWLPDzmED+iTHc/wcBAPJSTEz/6'
        '+Xk/gSvWO+xAFj9Sp3w/AVarOkTuGD+qVH8/AAAAABsbGz97e3s/AAAAAB0dHT91dXU/AAAAAB8fHz9vb28/'
        'AAAAACEhIT9paWk/AAAAACMjIz9jY2M/AAAAACUlJT9dXV0/AAAAACcnJz9XV1c/AAAAACkpKT9RUVE/AAAA'
        'ACsrKz9LS0s/AAAAAC0tLT9FRUU/AAAAAC8vLz8/Pz8/AAAAADExMT85OTk/AAAAADMzMz8zMzM/AAAAADU1'
        'NT8tLS0/AAAAADc3Nz8nJyc/AAAAADk5OT8hISE/AAAAADs7Oz8bGxs/AAAAAD09PT8VFRU/AAAAAD8/Pz8P'
        'Dw8/AAAAAEFBQT8JCQk/AAAAAENDQz8DAwM/AAAAAEVFRT/6+fk+AAAAAEdHRz/u7e0+AAAAAElJST/i4eE+'
        'AAAAAEtLSz/W1dU+gYCAOzMATT+aM80+oaCgPM7NTT/Pzs4+kZAQPWibTj8EatA+0dBQPQNpTz84BdI+iYiI'
        'PZ02UD9toNM+qaioPTcEUT+iO9U+ycjIPdLRUT/X1tY+6ejoPWyfUj8Mctg+hYQEPgdtUz9ADdo+lZQUPqE6'
        'VD91qNs+paQkPjsIVT+qQ90+tbQ0PtbVVT/f3t4+xcREPnCjVj8UeuA+1dRUPgtxVz9IFeI+5eRkPqU+WD99'
        'sOM+9fR0Pj8MWT+yS+U+g4KCPtrZWT/n5uY+i4qKPnSnWj8cgug+k5KSPg91Wz9RHeo+m5qaPqlCXD+FuOs+'
        'o6KiPkMQXT+6U+0+q6qqPt7dXT/v7u4+s7KyPnirXj8kivA+u7q6PhN5Xz9ZJfI+w8LCPq1GYD+NwPM+y8rK'
        'PkcUYT/CW/U+09LSPuLhYT/39vY+29raPnyvYj8skvg+4+LiPhd9Yz9hLfo+6+rqPrFKZD+VyPs+8/LyPksY'
        'ZT/KY/0++/r6PublZT///v4+goEBP4CzZj8aTQA/hoUFPxuBZz+0GgE/iokJP7VOaD9P6AE/jo0NP1AcaT/p'
        'tQI/kpERP+rpaT+EgwM/lpUVP4S3aj8eUQQ/mpkZPx+Faz+4HgU/np0dP7lSbD9T7AU/oqEhP1QgbT/tuQY/'
        'pqUlP+7tbT+Ihwc/qqkpP4i7bj8iVQg/rq0tPyOJbz+8Igk/srExP71WcD9X8Ak/trU1P1gkcT/xvQo/urk5'
        'P/LxcT+Miws/vr09P4y/cj8mWQw/wsFBPyeNcz/AJg0/xsVFP8FadD9b9A0/yslJP1wodT/1wQ4/zs1NP/b1'
        'dT+Qjw8/0tFRP5DDdj8qXRA/1tVVPyuRdz/EKhE/2tlZP8VeeD9f+BE/3t1dP2AseT/5xRI/4uFhP/r5eT+U'
        'kxM/5uVlP5THej8uYRQ/6ulpPy+Vez/ILhU/7u1tP8lifD9j/BU/8vFxP2QwfT/9yRY/9vV1P/79fT+Ylxc/'
        '+vl5P5jLfj8yZRg//v19PzOZfz/MMhk///5+Pwm3fj/RDhk//fx8PxslfD9B+Rc/+/p6Py2TeT+w4xY/+fh4'
        'Pz8Bdz8gzhU/9/Z2P1FvdD+QuBQ/9fR0P2PdcT//ohM/8/JyP3RLbz9vjRI/8fBwP4a5bD/edxE/7+5uP5gn'
        'aj9OYhA/7exsP6qVZz+9TA8/6+pqP7wDZT8tNw4/6ehoP85xYj+cIQ0/5+ZmP+DfXz8MDAw/5eRkP/JNXT98'
        '9go/4+JiPwS8Wj/r4Ak/4eBgPxYqWD9bywg/395ePyiYVT/KtQc/3dxcPzkGUz86oAY/29paP0t0UD+pigU/'
        '2dhYP13iTT8ZdQQ/19ZWP29QSz+IXwM/1dRUP4G+SD/4SQI/09JSP5MsRj9oNAE/0dBQP6WaQz/XHgA/z85O'
        'P7cIQT+NEv4+zcxMP8l2Pj9t5/s+y8pKP9vkOz9MvPk+ychIP+1SOT8rkfc+x8ZGP/7ANj8KZvU+xcREPxAv'
        'ND/pOvM+w8JCPyKdMT/ID/E+wcBAPzQLLz+n5O4+v74+P0Z5LD+Guew+vbw8P1jnKT9ljuo+u7o6P2pVJz9F'
        'Y+g+ubg4P3zDJD8kOOY+t7Y2P44xIj8DDeQ+tbQ0P6CfHz/i4eE+s7IyP7INHT/Btt8+sbAwP8N7Gj+gi90+'
        'r64uP9XpFz9/YNs+rawsP+dXFT9eNdk+q6oqP/nFEj89Ctc+qagoPws0ED8d39Q+p6YmPx2iDT/8s9I+paQk'
        'Py8QCz/biNA+o6IiP0F+CD+6Xc4+oaAgP1PsBT+ZMsw+n54eP2VaAz94B8o+nZwcP3fIAD9X3Mc+m5oaPxFt'
        '/D42scU+mZgYPzVJ9z4VhsM+l5YWP1kl8j71WsE+lZQUP3wB7T7UL78+k5ISP6Dd5z6zBL0+kZAQP8S54j6S'
        '2bo+j44OP+iV3T5xrrg+jYwMPwxy2D5Qg7Y+i4oKPy9O0z4vWLQ+iYgIP1Mqzj4OLbI+h4YGP3cGyT7tAbA+'
        'hYQEP5viwz7N1q0+g4ICP7++vj6sq6s+gYAAP+OauT6LgKk+goEBP9EsvD7q/qw+hIMDP61QwT51YLI+hoUF'
        'P4l0xj7/wbc+iIcHP2WYyz6KI70+iokJP0G80D4UhcI+jIsLPx7g1T6f5sc+jo0NP/oD2z4pSM0+kI8PP9Yn'
        '4D60qdI+kpERP7JL5T4+C9g+lJMTP45v6j7JbN0+lpUVP2qT7z5TzuI+mJcXP0e39D7eL+g+mpkZPyPb+T5o'
        'ke0+nJsbP//+/j7z8vI+np0dP24RAj99VPg+oJ8fP1yjBD8Itv0+oqEhP0o1Bz/JiwE/pKMjPzjHCT+OPAQ/'
        'pqUlPyZZDD9U7QY/qKcnPxTrDj8Zngk/qqkpPwJ9ET/eTgw/rKsrP/AOFD+j/w4/rq0tP96gFj9psBE/sK8v'
        'P8wyGT8uYRQ/srExP7rEGz/zERc/tLMzP6lWHj+4whk/trU1P5foID9+cxw/uLc3P4V6Iz9DJB8/urk5P3MM'
        'Jj8I1SE/vLs7P2GeKD/NhSQ/vr09P08wKz+TNic/wL8/Pz3CLT9Y5yk/wsFBPytUMD8dmCw/xMNDPxnmMj/i'
        'SC8/xsVFPwd4NT+o+TE/yMdHP/UJOD9tqjQ/yslJP+SbOj8yWzc/zMtLP9ItPT/3Czo/zs1NP8C/Pz+9vDw/'
        '0M9PP65RQj+CbT8/0tFRP5zjRD9HHkI/1NNTP4p1Rz8Mz0Q/1tVVP3gHSj/Sf0c/2NdXP2aZTD+XMEo/2tlZ'
        'P1QrTz9c4Uw/3NtbP0K9UT8hkk8/3t1dPzBPVD/nQlI/4N9fPx/hVj+s81Q/4uFhPw1zWT9xpFc/5ONjP/sE'
        'XD82VVo/5uVlP+mWXj/8BV0/6OdnP9coYT/Btl8/6ulpP8W6Yz+GZ2I/7OtrP7NMZj9LGGU/7u1tP6HeaD8R'
        'yWc/8O9vP49waz/WeWo/8vFxP30Cbj+bKm0/9PNzP2uUcD9g228/9vV1P1omcz8mjHI/+Pd3P0i4dT/rPHU/'
        '+vl5PzZKeD+w7Xc//Pt7PyTcej91nno//v19PxJufT87T30/AACAPwAAgD8AAIA/'
    ),
    'viridis': (
        'wLSIPhO2nzsVqag+JXqJPkpeHTwWvas+GjaKPrKdbzw6ya4+feiKPmhdozw+zbE+cZGLPn9p0TybyLQ+sTCM'
        'PgADAT2Vu7c+gsaMPtehGj1hpbo+wVKNPnXoND0jhr0+TtWNPoM1Tj23XcA+SE6OPv+zZj13K8M+sr2OPsGL'
        'fj1j78U+RiOPPprtij1Yqcg+KH+PPqdblj3zWMs+V9GPPv6ZoT0R/s0+sRmQPvevrD2RmNA+WFiQPs+itz0P'
        'KNM+Ko2QPsR3wj1prNU+SriQPo8zzT1bJdg+lNmQPknY1z3mkto+TvGQPpxp4j2l9Nw+Mv+QPqPp7D13St8+'
        'ZAORPu9Z9z06lOE+4/2QPkzeAD7M0eM+0O6QPlcJBj7rAuY+LNaQPp0uCz6VJ+g+9rOQPuhOED6rP+o+UYiQ'
        'PvVpFT4KS+w+flOQPo2AGj6QSe4+PBWQPvOSHz4dO/A+7s2PPiehJD7RH/I+lX2PPm2rKT6M9/M+UySPPoGx'
        'Lj4rwvU+SMKOPqezMz7Qf/c+l1eOPiCyOD5ZMPk+guSNPmmsPT7p0/o+TWmNPsKiQj6havw+1uWMPi2VRz5e'
        '9P0+gVqMPqmDTD5Dcf8+cceLPrFtUT7KcAA/Ci2LPodTVj6WIgE/bouKPuc0Wz4pzgE/veKJPtMRYD6jcwI/'
        'GjOJPgfqZD71EgM/LH2IPoS9aT5grAM/FsGHPgWMbj7VPwQ/1v6GPopVcz6WzQQ/9DaGPtIZeD6TVQU/kGmF'
        'Ph/ZfD4O2AU/D5eEPnXJgD4ZVQY/tr+DPnkjgz7VzAY/5+OCPt16hT51Pwc/xQOCPl/Phz73rAc/kh+BPv8g'
        'ij6QFQg/tTeAPr1vjD5weQg/mph+Ppm7jj6p2Ag/Brx8PnEEkT5uMwk/8dl6PiNKkz7fiQk/nfJ4PhWNlT4v'
        '3Ak/1QZ3PuLMlz5eKgo/Hhd1PqsJmj7BdAo/vCNzPnBDnD5Wuwo/ui1xPlN6nj5h/go/oDVvPhCuoD7zPQs/'
        '8zttPsreoj4+egs/s0BrPoAMpT5jsws/7URpPlQ3pz6F6Qs/oUhnPkZfqT7FHAw/mExlPlWEqz40TQw/FlFj'
        'PoOmrT4Deww/n1ZhPu/Frz5Vpgw/eV1fPpvisT5Kzww/J2ZdPmX8sz7k9Qw/73BbPrITtj5lGg0/E35ZPl8o'
        'uD7ePA0/GY5XPm06uj5fXQ0/RaFVPv1JvD4cfA0/2LdTPhFXvj4TmQ0/GNJRPshhwD5XtA0/v+9PPiNqwj4H'
        'zg0/mRFOPmVwxD425g0/YTdMPm10xj4F/Q0/F2FKPlx2yD5zEg4/ho9IPjJ2yj6RJg4/J8JGPhB0zD6COQ4/'
        'PPlEPhlwzj5FSw4/xjRDPk1q0D7ZWw4/CHVBPsxi0j5haw4/fLk/PpZZ1D7deQ4/ZAI+Ps9O1j5dhw4/wk88'
        'PpZC2D7ikw4/UaE6Pso02j5rnw4/z/Y4Pq8l3D4Iqg4/wlA3PkQV3j68sw4/YK41PooD4D6UvA4/qg80PsPw'
        '4T5yxA4/4nQyPs/c4z51yw4/QN0wPu/H5T6N0Q4/w0gvPgOy5z7L1g4/rrctPiyb6T4O2w4/OSksPoyD6z52'
        '3g4/pp0qPiNr7T7j4A4/bhQpPhFS7z5U4g4/UI0nPlg48T7K4g4/jQgmPvcd8z5D4g4/XoUkPjID9T6g4A4/'
        'wAMjPsXn9j7f3Q4/toMhPhTM+D7x2Q4/PgUgPv+v+j7l1A4/04cePoaT/D6azg4/dAsdPsl2/j4Axw4/ZJAb'
        'PuQsAD8Gvg4/YRYaPlQeAT+8sw4/rp0YPqEPAj/wpw4/SiYXPu8AAz/Dmg4/NrAVPhvyAz/0iw4/tDsUPkfj'
        'BD+Bew4/gsgSPnTUBT9ZaQ4/aVcRPqDFBj9tVQ4/q+gPPru2Bz+rPw4/jXwOPuenCD8CKA4/lBMNPhOZCT9S'
        'Dg4/iq4LPlCKCj+Z8g0/vk4KPnx7Cz/Y1A0/7fMIPspsDD/dtA0/Zp8HPgdeDT+Wkg0/9FEGPmZPDj/0bQ0/'
        'KA0FPsRADz/2Rg0/idEDPiMyED9YHQ0/MKECPpIjET898Qw/5XwBPgEVEj9hwgw/SWcAPoEGEz/mkAw/zsL+'
        'PfD3Ez+JXAw/K9r8PXDpFD9bJQw/2xj7PeDaFT8p6ws/iIL5PU/MFj/zrQs/cRz4Pb69Fz+YbQs/yOr2PR2v'
        'GD8XKgs/y/L1PWqgGT8/4wo/Mjn1PaeRGj8xmQo/tcL0PcOCGz+6Swo/DJT0Pb1zHD+5+gk/gbP0PaZkHT8v'
        'pgk/wCT1PVxVHj8JTgk/B+31PfFFHz858gg/DhH3PUQ2ID+rkgg/FJb4PWMmIT9iLwg/t376PVEWIj8qyAc/'
        'NdD8PeoFIz8DXQc/qIz/PUH1Iz/u7QY/mlsBPjLkJD/IegY/PSkDPuHSJT+CAwY/STAFPhrBJj8aiAU/Q3EH'
        'Pv+uJz+BCAU/s+wJPl6cKD+lhAQ/mKIMPlmJKT92/AM/NpMPPrx1Kj/0bwM/Br4SPqphKz/83gI/gSIWPgFN'
        'LD+hSQI/ZsAZPrA3LT/RrwE/ZJYdPskhLj9rEQE/saMhPjkLLz9+bgA/huclPvHzLz/Wjf8+TmAqPvDbMD+D'
        'Nf4+/gwvPibDMT+/0/w+iewzPpOpMj+taPs+Gv04PhWPMz/p8/k+5j0+Pr1zND+0dfg+Ga1DPnlXNT/u7fY+'
        '6UlJPks6Nj90XPU+fxJPPhEcNz9IwfM+0QVVPsr8Nz9pHPI+0SJbPnfcOD/XbfA+MGhhPvW6OT8tte4+ndRn'
        'PmeYOj+u8uw+DmduPop0Oz9bJus+dR51Pn9PPD/wT+k+xvl7PjUpPT+xb+c++nuBPooBPj97heU++guFPpDY'
        'Pj8ukeM+fqyIPiWuPz/JkuE+Ql2MPkmCQD8rit8+wR2QPvxUQT91d90+dO2TPhwmQj+nWts+GMyXPqn1Qj/C'
        'M9k+SbmbPqTDQz/FAtc+orSfPvyPRD+wx9Q+Ab6jPp9aRT+EgtI+4dSnPo4jRj8eM9A+HvmrPqfqRj9e2c0+'
        'eCqwPvuvRz+Gdcs+iGi0PmlzSD+WB8k+C7O4PvA0ST+Oj8Y+ngm9PpD0ST9ODcQ+QGzBPimySj84gcE+jNrF'
        'PsptSz/q6r4+P1TKPlInTD+lSrw+ONnOPtPeTD9qoLk+VWnTPhiUTT/267Y+UwTYPjRHTj+MLbQ+zqncPhb4'
        'Tj9NZbE+o1nhPr2mTz86k64+kBPmPhpTUD90t6s+UtfqPir9UD/60ag+paTvPs+kUT8R46U+Z3v0PidKUj90'
        '6qI+eVv5PgPtUj+K6J8+UkT+PmGNUz9y3Zw++poBP1IrVD8MyZk+DRgEP8XGVD+9q5Y+QpkGP6tfVT9ihZM+'
        'dR4JPwH2VT8/VpA+dqcLP7mJVj/aHo0+MzQOP+MaVz8z34k+esQQP36pVz/Ql4Y+GVgTP3o1WD/USIM+/u4V'
        'P8a+WD8A5X8+6IgYP4RFWT89K3k+xCUbP6PJWT+hZHI+YcUdPyNLWj/Akms+e2cgPwTKWj+mtmQ+AgwjP1ZG'
        'Wz+i0V0+orIlPxrAWz/N5VY+OlsoP1A3XD+69E8+lgUrP/erXD8IAUk+dbEtPzIeXT8TDUI+ol4wPwCOXT9D'
        'HDs+3QwzP2H7XT++MTQ+4Ls1P3dmXj+1US0+i2s4P0LPXj9ngSY+ixs7P+M1Xz8Rxh8+m8s9P1uaXz+FJhk+'
        'eHtAP8r8Xz9cqhI+4CpDP1NdYD+BWgw+odlFP/W7YD9wQQY+VYdIP9IYYT8ragA+2zNLPx10YT8uxfU9395N'
        'P8TNYT/Fcus9DohQPwsmYj+c/eE9RS9TPwN9Yj9MiNk9QdRVP8zSYj8RONI9sHZYP4knYz+QMMw9XRZbP1t7'
        'Yz/qlMc9B7NdP2TOYz8Cg8Q9jExgP8UgZD9vEsM9qOJiP59yZD9yU8M9OnVlPwXEZD9JS8U9/wNoPzgVZT/D'
        '9cg91o5qPzhmZT+3RM49SBVtP2u3ZT8tI9U9aJdvP68IZj/Jc909MxVyP0daZj+cF+c9io50PzKsZj8Y7fE9'
        'SwN3P6T+Zj/H1P09ZHN5P61RZz8VVwU+xt57P12lZz+6Lgw+gEV+P+j5Zz/1YxM+'
    ),
    'cividis': (
        'AAAAAM1aCj5TCJw+AAAAALNhDT4oSZ8+AAAAALZlED63maI+AAAAAORnEz744KU+AAAAAO1mFj6LNKk+AAAA'
        'ANBiGT7Jk6w+AAAAAFBWHD74+a8+AAAAACYbHz68dLM+AAAAAO24IT7+DLc+AAAAAM1YJD4zpLo+AAAAAK34'
        'Jj5nQ74+AAAAAI2YKT4D7sE+AAAAAKs9LD7ylMU+AAAAADLmLj5nRMk+AAAAAAOVMT4S+8w+AAAAANdOND7v'
        'rdA+AAAAAN8XNz7yW9Q+AAAAAPn3OT7n/dc+AAAAAK36PD7wi9s+AAAAAKVmPz4N/t4+AAAAAKlMQT5nDuE+'
        'AAAAAGaIQz7l1eE+AAAAAL0BRj5JFOI+iA9sO+WcSD6tFOI+XD6SPO1KSz5C6+E+xoUDPRwHTj6SruE+dEE9'
        'PfPLUD5fYeE+xR1vPY2WUz41CuE+GD+NPZ1lVj6nsuA+nwWhPYI2WT5MT+A+2iCzPT4JXD5K698+h+HDPc7d'
        'Xj4eid8+58PTPRyyYT7eH98+qaDiPa2GZD4awd4+j97wPYFbZz6eXd4+SIz+PYwvaj7f+d0+GM4FPlMDbT40'
        'nd0+Kh0MPlLWbz6BQt0+y0cSPsqocj784Nw+jzQYPjV6dT6Hi9w+mPYdPl5LeD6wONw+DJEjPjcbez4Y69s+'
        'YhMpPonqfT7Umds+YHMuPqtcgD5qTds+p7MzPmnDgT5KB9s+x9U4PgYqgz7vxto+ZOc9PmCQhD71g9o+yt5C'
        'PjT2hT7LR9o+Br1HPsRbhz62Eto+745MPjPBiD6+2tk+TUpRPj4mij4dqtk+s/BVPiaLiz6RgNk+qI1aPqrv'
        'jD5xVdk+ehdfPg1Ujj6HMdk+LZljPiy4jz5BC9k+TgloPkwckT5T7Ng+c2lsPiiAkj671Ng+TMNwPuPjkz5N'
        'u9g+NA51Pp1HlT5Yqdg+IlR5PhWrlj5Kldg+Kox9Po0OmD6UiNg+jNuAPgRymT7Pgtg+LO+CPlrVmj4Ue9g+'
        'pPyEPrA4nD6Netg+qwiHPgacnT7Nd9g+Dw+JPlz/nj7+e9g+RBSLPrJioD4Xftg+ChCNPirGoT60kNg+9Q6P'
        'PqIpoz6Fl9g+1QSRPjuNpD4dr9g+L/qSPtTwpT5ZxNg+v+6UPm1Upz4419g+296WPkq4qD5O8dg+o8qYPkcc'
        'qj79Etk+5bWaPkWAqz5yMtk+F52cPobkrD6jWdk+BoSePsdIrj4Tftk+J2egPm2trz5Uqdk+F0aiPjQSsT61'
        '3Nk+ByWkPh13sj4fDto+GQSmPifcsz5xPdo+O9+nPpZBtT5+dNo+9rapPiantj6esto+sI6rPvoMuD4L79o+'
        'jGatPhFzuT7DKds+3jqvPknZuj4WbNs+yAuxPgdAvD6Jtts+09yyPuemvT6s/9s+Q660PukNvz6VRtw+bHy2'
        'PnF1wD7VlNw+6Ua4PjzdwT6z7dw+mBW6PkpFwz7vON0+Vd27Pt6txD5wl90+AKm9PnIWxj5G6t0+uW2/Pq5/'
        'xz6kUN4+xjbBPi3pyD7nqd4+JvzCPvBSyj7pDd8+xr7EPji9yz6ned8+RYHGPsQnzT5x5t8+8kTIPtWSzj4e'
        'TuA+0QTKPir+zz7GwuA+esXLPuRp0T7CM+E+qYbNPiTW0j57pOE+kUTPPshC1D7mHuI+AAPRPtGv1T6JmOI+'
        'J77SPj8d1z6GHOM+1XnUPjOL2D66n+M+TDbWPq352T5xIOQ+W+/XPmpo2z4AruQ+VKnZPs/X3D7jN+U+X1/b'
        'PplH3j6B0eU+HhfdPum33z4KZOY+V87ePp4o4T4J++Y+mYPgPtmZ4j49mec+7DTiPrsL5D7+Reg+cOrjPuF9'
        '5T6w5ug+2JrlPmvw5j5vm+k+9UznPuBj6D4wSOo+Mv/oPvHW6T7n/uo+867qPmZK6z4Fwes+71jsPlnA7D4z'
        'h+w+iA3uPhE07j4cQu0+/b7vPpOo7z5sCO4+lGjxPqsh8T5Yxu4+jxrzPhya8j7ic+8+zNT0PuQR9D50DPA+'
        'KZf2PpiK9T5NhfA+Z2T4PtED9z4s1vA+fjb6Ppp7+D72J/E+3Qv8Phf1+T5KYvE+T+j9PlBu+z5ZifE+SMX/'
        'PlPo/D4urvE+u9AAP0Fj/j720fE++MEBP1He/z6b4vE+wLICPzatAD8T8vE+UaQDP3ZrAT/f/fE+aJYEPwsq'
        'Aj+nBvI+ZYoFP/PoAj+9/fE+NX0GPy+oAz9+API+LnIHP65nBD8o8fE+e2cIP5EnBT+L3vE+ilsJP7jnBT8f'
        '2PE+j1EKP0SoBj9Zv/E+G0gLPyNpBz8Ko/E+Pj8MP0UqCD8wg/E+cjYNP93rCD90YPE+PC4OP7itCT8uOvE+'
        'fCYPP/hvCj+AEPE+7x4QP5wyCz/O4/A+8BkRP4T1Cz9EovA+TRMSP9C4DD9+bvA+/gwTP5F8DT9QN/A+RgcU'
        'P5ZADj+Y/O8+pwMVP/8EDz8qre8+l/4VP97JDz+ga+8+DfoWPwCPED9sJu8+nfcXP5dUET8dzO4+uvMYP5Ma'
        'Ej8XgO4+VvIZP9LgEj8uHu4+HO8aP6inEz82y+0+Tu4bP9JuFD/2Ye0+EOwcP2E2FT/IB+0+A+odP2X+FT9U'
        'quw+dOoeP73GFj8zNuw+U+kfP4qPFz+J0es+W+ogP7xYGD8RVus+6ushP1MiGT+I1uo+5usiP3DsGT8fZ+o+'
        'HO4jP/K2Gj+D4Ok+4e4kP9iBGz/kaek+4fElPzRNHD+t2+g+I/UmPxUZHT/tSeg+FvcnP0vlHT+OyOc+Ivso'
        'PweyHj93L+c+gv8pPyh/Hz+0kuY+kwIrP75MID+4BuY+mgcsP9oaIT+eYuU+Fw0tP2zpIT+VuuQ+GxMuP2O4'
        'Ij+dDuQ+WRcvP/CHIz/edOM+8x0wP+JXJD/0weI+AyUxPzkoJT8cC+I+EywyPzj5JT8eUeE+uTMzP5vKJj9T'
        'k+A+xTs0P3OcJz+70d8+4UM1P+NuKD8gDd8+g0w2P8hBKT+VRN4+YFc3PxIVKj+zYd0+eGA4PwPpKj95ktw+'
        'BWo5P2q9Kz9Rv9s+GXQ6P0eSLD9c6No+AoA7P7pnLT+U99k+eoo8P7Q9Lj8zGtk+Ppc9PxIULz+OIdg+TaI+'
        'PxjrLz/APdc+hq8/P6TCMD/RPtY+I71AP6aaMT/RO9U+HclBPz9zMj8vTtQ+MNdCP15MMz9KRdM+qOVDPwMm'
        'ND92ONI+UfREPz8ANT8CKdE+LgNGPwHbNT+LFtA+IxRHP0q2Nj/F584+uCNIPymSNz99zs0+ATVJP6BuOD8T'
        'msw+C0VKP51LOT8He8s+HVdLPyApOj+KP8o+L2lMP0oHOz95Ask+lntNP/vlOz8iwsc+UI5OP0PFPD+EfsY+'
        'PKFPPyKlPT+sOMU+zLVQP5iFPj+Q18M+sMpRP5VmPz8uc8I+599SPyhIQD/IC8E+H/VTP2MqQT8zo78+iQpV'
        'PzUNQj8NOb4+NiBWP43wQj9ozLw+qDdXP43UQz8PQ7s+Gk9YPyS5RD8wubk+rmZZP1KeRT9mLrg+9n9aPyeE'
        'Rj8rh7Y+X5lbP4NqRz9d3rQ+6rJcP4dRSD+kNLM+xM1dPyI5ST/BcbE+T+deP2QhSj9Yya8+vANgPz0KSz8x'
        '660+6x5hP67zSz/IJ6w+eTtiP7XdTD9rSqo+R1ljP2XITT+LVKg+83ZkP7yzTj81YqY+3ZVlP6mfTz/BV6Q+'
        't7RmPy6MUD+UUKI+rtRnP0p5UT/9MqA+w/VoPw5nUj8IAJ4+lBZqP2lVUz+A05s+UDhrP1tEVD9blJk+A1xs'
        'P9MzVT85Kpc+Un9tP/IjVj/3ypQ+WaNuP6kUVz/dXpI+88hvP/cFWD/7zo8+A+9wP7r3WD+gN40+YRZyPxTq'
        'WT8sg4o+3j5zP+TcWj85uYc+3Gh0PznQWz99y4Q+o5N1P/TDXD8C04E+UcB2PwK4XT85Yn0+lu13P3WsXj/4'
        'GXc+AB55P/mgXz8rT3A+yk96P32VYD/GbGk+7IR7P76JYT/YLWI+PL98P+F8Yj/BdFo+AAJ+PzNtYz80ZlI+'
        'S65+P6KYZD/jU1A+o8h+P378ZT/filQ+Sdl+P8NjZz+Fd1k+n+h+P8XKaD+g/14+'
    ),
    'gist_earth': (
        'AAAAAAAAAAAAAAAAeUYrOwAAAACZvSw+eUarOwAAAADG+2I+2nQAPAAAAACEEYc+eUYrPAAAAAAkpZw+FxhW'
        'PAAAAADFOLI+2nSAPAAAAABlzMc+qd2VPAAAAAAGYN0+eUarPBDwETxb1Og+SK/APIXckjwtRek+FxjWPALB'
        '3Dxbouk+5oDrPL9SEz2I/+k+2nQAPf5EOD21XOo+QikLPTw3XT3iueo+qd0VPb0UgT0QF+s+EZIgPd2Nkz09'
        'dOs+eUYrPfwGpj1q0es+4Po1PRuAuD2XLuw+SK9APTr5yj3Fi+w+r2NLPVpy3T3y6Ow+FxhWPXnr7z0fRu0+'
        'fsxgPUwyAT5Mo+0+5oBrPdxuCj56AO4+TTV2PWurEz6nXe4+2nSAPfvnHD7Uuu4+Ds+FPYokJj4BGO8+QimL'
        'PRphLz4ude8+doOQPaqdOD5c0u8+qd2VPf/ZQT6JL/A+3TebPWw0Sj62jPA+EZKgPdiOUj7j6fA+ReylPUTp'
        'Wj4RR/E+eUarPbBDYz4+pPE+rKCwPRyeaz5rAfI+4Pq1PYj4cz6YXvI+FFW7PfRSfD7Gu/I+SK/APbBWgj7z'
        'GPM+ewnGPeaDhj4gdvM+r2PLPRyxij5N0/M+473QPVLejj57MPQ+FxjWPYkLkz6ojfQ+SnLbPb84lz7V6vQ+'
        'fszgPctlmz4CSPU+sibmPQYnnz4wpfU+5oDrPUHooj5dAvY+GdvwPXyppj6KX/Y+TTX2Pbdqqj63vPY+gY/7'
        'PfIrrj7lGfc+2nQAPi3tsT4Sd/c+9CEDPmiutT4/1Pc+Ds8FPqNvuT5sMfg+KHwIPt4wvT6Zjvg+QikLPhny'
        'wD7H6/g+XNYNPrGxxD70SPk+doMQPgvexz4hpvk+kDATPmYKyz5OA/o+qd0VPsA2zj58YPo+w4oYPhpj0T6p'
        'vfo+3TcbPnWP1D7WGvs+9+QdPs+71z4DePs+EZIgPino2j4x1fs+Kz8jPoQU3j5eMvw+RewlPt5A4T6Lj/w+'
        'X5koPjht5D647Pw+eUYrPpOZ5z7mSf0+kvMtPu3F6j4Tp/0+rKAwPkfy7T5ABP4+xk0zPqIe8T5tYf4+4Po1'
        'PvxK9D6bvv4++qc4PlZ39z7IG/8+FFU7PrGj+j71eP8+LgI+PgvQ/T4i1v8+SK9APjN+AD+oGQA/jZZCPj8V'
        'AT/Jxv0+bHtEPjKpAT+YUfs+SmBGPiU9Aj9n3Pg+KUVIPhjRAj82Z/Y+BypKPgtlAz8E8vM+5g5MPv74Az/T'
        'fPE+xPNNPvGMBD+iB+8+o9hPPuQgBT9xkuw+gb1RPte0BT8/Heo+YKJTPspIBj8OqOc+PodVPr3cBj/dMuU+'
        'HGxXPrBwBz+rveI++1BZPqMECD96SOA+2TVbPpaYCD9J090+uBpdPoksCT8YXts+lv9ePnzACT/m6Ng+deRg'
        'Pm9UCj+1c9Y+U8liPmLoCj+E/tM+Mq5kPlV8Cz9TidE+EJNmPkgQDD8hFM8+73doPjukDD/wnsw+zVxqPi44'
        'DT+/Kco+rEFsPiHMDT+NtMc+iiZuPhRgDj9cP8U+aQtwPgf0Dj8rysI+R/BxPvqHDz/6VMA+JtVzPu0bED/I'
        '370+BLp1PuCvED+Xars+4553PtNDET9m9bg+wYN5PsbXET81gLY+oGh7PrhrEj8DC7Q+fk19Pqv/Ej/SlbE+'
        'XTJ/Pp6TEz+hIK8+nouAPpEnFD9wq6w+DX6BPoS7FD8+Nqo+fHCCPndPFT8Nwac+62KDPmrjFT/cS6U+W1WE'
        'Pl13Fj+q1qI+ykeFPlALFz95YaA+OTqGPkOfFz9I7J0+qCyHPjYzGD8Xd5s+Fx+IPinHGD/lAZk+hxGJPhxb'
        'GT+0jJY+9gOKPg/vGT+DF5Q+zPuKPgKDGj9SopE+WnKPPvUWGz8gLY8+6eiTPuiqGz/vt4w+d1+YPts+HD+o'
        '240+BdacPs7SHD9HB48+lEyhPsFmHT/mMpA+IsOlPrT6HT+EXpE+sTmqPqeOHj8jipI+P7CuPpoiHz/BtZM+'
        'zSazPo22Hz9g4ZQ+XJ23PoBKID/+DJY+6hO8PnPeID+dOJc+eYrAPmZyIT88ZJg+BwHFPlkGIj/aj5k+lXfJ'
        'PkyaIj95u5o+JO7NPj8uIz8X55s+smTSPjLCIz+2Ep0+QdvWPj4zJD9UPp4+z1HbPgOkJD/zaZ8+XcjfPscU'
        'JT+RlaA+7D7kPoyFJT8wwaE+erXoPlD2JT/P7KI+CSztPhRnJj9tGKQ+HaHxPtnXJj/zuqQ+tvD0Pp1IJz9n'
        'XaU+TkD4PmG5Jz/b/6U+54/7PiYqKD9QoqY+f9/+PuqaKD/ERKc+jBcBP64LKT8456c+WL8CP3N8KT+siag+'
        'JGcEPzftKT8gLKk+8A4GP/xdKj+Vzqk+vbYHP8DOKj8Jcao+iV4JP4Q/Kz99E6s+VQYLP0mwKz/xtas+Ia4M'
        'Pw0hLD9mWKw+7lUOP9GRLD/a+qw+uv0PP5YCLT9Ona0+hqURP1pzLT/CP64+Uk0TPx7kLT824q4+HvUUP+NU'
        'Lj+rhK8+65wWP6fFLj8fJ7A+t0QYP2s2Lz+TybA+g+wZPzCnLz8HbLE+T5QbP/QXMD97DrI+HDwdP7mIMD/w'
        'sLI+6OMeP335MD9kU7M+tIsgP0FqMT/Y9bM+gDMiPwbbMT9MmLQ+TNsjP8pLMj/BOrU+GYMlP468Mj813bU+'
        '5SonP1MtMz+pf7Y+sdIoPxeeMz8dIrc+fXoqP9sOND+RxLc+SiIsP6B/ND8GZ7g+FsotP2TwND96Cbk+4nEv'
        'PyhhNT/uq7k+rhkxP+3RNT9iTro+esEyP7FCNj/X8Lo+R2k0P3azNj9Lk7s+ExE2PzokNz+/Nbw+tbU3P6WR'
        'Nz8z2Lw+ICE4P7CzNj+ner0+i4w4P7vVNT8cHb4+9vc4P8b3ND+Qv74+YWM5P9AZND8EYr8+y845P9s7Mz94'
        'BMA+Njo6P+ZdMj/tpsA+oaU6P/F/MT9hScE+DBE7P/yhMD/V68E+d3w7PwbELz9JjsI+4uc7PxHmLj+9MMM+'
        'TVM8PxwILj8y08M+t748PycqLT+mdcQ+Iio9PzFMLD8aGMU+jZU9PzxuKz+OusU++AA+P0eQKj8DXcY+Y2w+'
        'P1KyKT93/8Y+ztc+P1zUKD/rocc+OEM/P2f2Jz9fRMg+o64/P3IYJz/T5sg+DhpAP306Jj9Iick+eYVAP4hc'
        'JT+8K8o+5PBAP5J+JD8H0so+7l1BP9OjIz9Nvc8+ZH1CP8EqJD+SqNQ+2pxDPwibJD/Yk9k+ULxEPw8LJT8e'
        'f94+xttFPxZ7JT9jauM+PPtGP1HsJT+pVeg+shpIP4nJJj/vQO0+KDpJP8GmJz81LPI+nllKP3yFKD96F/c+'
        'FHlLPzhkKT/AAvw+iphMP/VCKj8DdwA/ALhNP7IhKz+m7AI/dtdOP24ALD9JYgU/7PZPPyvfLD/s1wc/YhZR'
        'P+e9LT+OTQo/2DVSP6ScLj8xwww/TlVTP2F7Lz/UOA8/xHRUPx1aMD93rhE/OpRVP9o4MT8aJBQ/sLNWP5YX'
        'Mj+9mRY/JtNXP1P2Mj9gDxk/nPJYPx1mND8ChRs/EhJaPyTXNT+l+h0/iDFbP8FGNz9IcCA//lBcP162OD/r'
        '5SI/dHBdPxsXOj+OWyU/6o9eP6l3Oz8x0Sc/YK9fPzjYPD97Ryo/1s5gP0Y6Pj8iTi0/TO5hP/swQD/JVDA/'
        'wg1jP68nQj9wWzM/OC1kP2MeRD8WYjY/rkxlPxgVRj+9aDk/JGxmP8wLSD9kbzw/motnP4ACSj8Ldj8/EKto'
        'PzX5Sz+yfEI/hsppP+nvTT9Zg0U//OlqP53mTz8Aikg/cglsP1LdUT+nkEs/6ChtPwbUUz9Ol04/XkhuP9Ag'
        'Vj/1nVE/1GdvPx9uWD+cpFQ/SodwP267Wj9Dq1c/wKZxP70IXT/qsVo/NsZyPw1dXz+QuF0/rOVzP6qxYT83'
        'v2A/IgV1PzegZD/exWM/mCR2P8OOZz+FzGY/DkR3P1B9aj8s02k/hGN4P91rbT/T2Ww/+oJ5P2lacD964G8/'
        'cKJ6P/ZIcz8h53I/5sF7P4M3dj/I7XU/XOF8PxAmeT9v9Hg/0gB+Pxb7ez8W+3s/'
    ),
    'Greys_r': (
        'AAAAAAAAAAAAAAAAvimVO74plTu+KZU7vikVPL4pFTy+KRU8nb5fPJ2+Xzydvl88vimVPL4plTy+KZU8LnS6'
        'PC50ujwudLo8nb7fPJ2+3zydvt88h4QCPYeEAj2HhAI9vikVPb4pFT2+KRU99s4nPfbOJz32zic9LnQ6PS50'
        'Oj0udDo9ZhlNPWYZTT1mGU09nb5fPZ2+Xz2dvl891WNyPdVjcj3VY3I9h4SCPYeEgj2HhII9IteLPSLXiz0i'
        '14s9vimVPb4plT2+KZU9WnyePVp8nj1afJ499s6nPfbOpz32zqc9kiGxPZIhsT2SIbE9LnS6PS50uj0udLo9'
        'ysbDPcrGwz3KxsM9ZhnNPWYZzT1mGc09AmzWPQJs1j0CbNY9nb7fPZ2+3z2dvt89ORHpPTkR6T05Eek91WPy'
        'PdVj8j3VY/I9cbb7PXG2+z1xtvs9h4QCPoeEAj6HhAI+1C0HPtQtBz7ULQc+ItcLPiLXCz4i1ws+cIAQPnCA'
        'ED5wgBA+/0kVPv9JFT7/SRU+UPUaPlD1Gj5Q9Ro+oaAgPqGgID6hoCA+8ksmPvJLJj7ySyY+Q/crPkP3Kz5D'
        '9ys+lKIxPpSiMT6UojE+5E03PuRNNz7kTTc+Nfk8PjX5PD41+Tw+hqRCPoakQj6GpEI+109IPtdPSD7XT0g+'
        'KPtNPij7TT4o+00+eaZTPnmmUz55plM+ylFZPspRWT7KUVk+G/1ePhv9Xj4b/V4+bKhkPmyoZD5sqGQ+vVNq'
        'Pr1Taj69U2o+Dv9vPg7/bz4O/28+X6p1Pl+qdT5fqnU+sFV7PrBVez6wVXs+gYCAPoGAgD6BgIA+KVaDPilW'
        'gz4pVoM+0SuGPtErhj7RK4Y+egGJPnoBiT56AYk+IteLPiLXiz4i14s+y6yOPsusjj7LrI4+c4KRPnOCkT5z'
        'gpE+HFiUPhxYlD4cWJQ+xC2XPsQtlz7ELZc+bQOaPm0Dmj5tA5o+FdmcPhXZnD4V2Zw+vq6fPr6unz6+rp8+'
        'ZoSiPmaEoj5mhKI+rimlPq4ppT6uKaU+1D2nPtQ9pz7UPac++1GpPvtRqT77Uak+IWarPiFmqz4hZqs+R3qt'
        'Pkd6rT5Heq0+bY6vPm2Orz5tjq8+lKKxPpSisT6UorE+urazPrq2sz66trM+4Mq1PuDKtT7gyrU+Bt+3Pgbf'
        'tz4G37c+LPO5PizzuT4s87k+Uwe8PlMHvD5TB7w+eRu+Pnkbvj55G74+ny/APp8vwD6fL8A+xUPCPsVDwj7F'
        'Q8I+61fEPutXxD7rV8Q+EmzGPhJsxj4SbMY+OIDIPjiAyD44gMg+XpTKPl6Uyj5elMo+hKjMPoSozD6EqMw+'
        'q7zOPqu8zj6rvM4+0dDQPtHQ0D7R0NA+9+TSPvfk0j735NI+HfnUPh351D4d+dQ+Qw3XPkMN1z5DDdc+aiHZ'
        'Pmoh2T5qIdk+kDXbPpA12z6QNds+tkndPrZJ3T62Sd0+3F3fPtxd3z7cXd8+A3LhPgNy4T4DcuE+KYbjPimG'
        '4z4phuM+T5rlPk+a5T5PmuU+jbrnPo265z6Nuuc+9O7pPvTu6T707uk+WyPsPlsj7D5bI+w+wVfuPsFX7j7B'
        'V+4+KIzwPiiM8D4ojPA+jsDyPo7A8j6OwPI+9fT0PvX09D719PQ+XCn3Plwp9z5cKfc+wl35PsJd+T7CXfk+'
        'KZL7PimS+z4pkvs+j8b9Po/G/T6Pxv0+9vr/Pvb6/z72+v8+rhcBP64XAT+uFwE/4jECP+IxAj/iMQI/FUwD'
        'PxVMAz8VTAM/SGYEP0hmBD9IZgQ/e4AFP3uABT97gAU/r5oGP6+aBj+vmgY/4rQHP+K0Bz/itAc/Fc8IPxXP'
        'CD8Vzwg/SekJP0npCT9J6Qk/fAMLP3wDCz98Aws/rx0MP68dDD+vHQw/4zcNP+M3DT/jNw0/FlIOPxZSDj8W'
        'Ug4/SWwPP0lsDz9JbA8/fIYQP3yGED98hhA/sKARP7CgET+woBE/47oSP+O6Ej/juhI/FtUTPxbVEz8W1RM/'
        'Su8UP0rvFD9K7xQ/fQkWP30JFj99CRY/0DMXP9AzFz/QMxc/RG4YP0RuGD9Ebhg/uKgZP7ioGT+4qBk/K+Ma'
        'PyvjGj8r4xo/nx0cP58dHD+fHRw/E1gdPxNYHT8TWB0/hpIeP4aSHj+Gkh4/+swfP/rMHz/6zB8/bgchP24H'
        'IT9uByE/4kEiP+JBIj/iQSI/VXwjP1V8Iz9VfCM/ybYkP8m2JD/JtiQ/PfElPz3xJT898SU/sCsnP7ArJz+w'
        'Kyc/JGYoPyRmKD8kZig/mKApP5igKT+YoCk/C9sqPwvbKj8L2yo/fxUsP38VLD9/FSw/808tP/NPLT/zTy0/'
        'ZoouP2aKLj9mii4/2sQvP9rELz/axC8/Tv8wP07/MD9O/zA/wTkyP8E5Mj/BOTI/NXQzPzV0Mz81dDM/qa40'
        'P6muND+prjQ/HOk1PxzpNT8c6TU/kCM3P5AjNz+QIzc/BF44PwReOD8EXjg/d5g5P3eYOT93mDk/69I6P+vS'
        'Oj/r0jo/Xw08P18NPD9fDTw/0kc9P9JHPT/SRz0/10o+P9dKPj/XSj4/miw/P5osPz+aLD8/XQ5AP10OQD9d'
        'DkA/H/BAPx/wQD8f8EA/4tFBP+LRQT/i0UE/pbNCP6WzQj+ls0I/Z5VDP2eVQz9nlUM/KndEPyp3RD8qd0Q/'
        '7VhFP+1YRT/tWEU/rzpGP686Rj+vOkY/chxHP3IcRz9yHEc/NP5HPzT+Rz80/kc/999IP/ffSD/330g/usFJ'
        'P7rBST+6wUk/fKNKP3yjSj98o0o/P4VLPz+FSz8/hUs/AmdMPwJnTD8CZ0w/xEhNP8RITT/ESE0/hypOP4cq'
        'Tj+HKk4/SgxPP0oMTz9KDE8/DO5PPwzuTz8M7k8/z89QP8/PUD/Pz1A/kbFRP5GxUT+RsVE/VJNSP1STUj9U'
        'k1I/F3VTPxd1Uz8XdVM/2VZUP9lWVD/ZVlQ/nDhVP5w4VT+cOFU/XxpWP18aVj9fGlY/IfxWPyH8Vj8h/FY/'
        '5N1XP+TdVz/k3Vc/p79YP6e/WD+nv1g/aaFZP2mhWT9poVk/72RaP+9kWj/vZFo/Yh5bP2IeWz9iHls/1Ndb'
        'P9TXWz/U11s/RpFcP0aRXD9GkVw/uEpdP7hKXT+4Sl0/KgRePyoEXj8qBF4/nL1eP5y9Xj+cvV4/D3dfPw93'
        'Xz8Pd18/gTBgP4EwYD+BMGA/8+lgP/PpYD/z6WA/ZaNhP2WjYT9lo2E/11xiP9dcYj/XXGI/SRZjP0kWYz9J'
        'FmM/vM9jP7zPYz+8z2M/LolkPy6JZD8uiWQ/oEJlP6BCZT+gQmU/EvxlPxL8ZT8S/GU/hLVmP4S1Zj+EtWY/'
        '9m5nP/ZuZz/2bmc/aShoP2koaD9pKGg/2+FoP9vhaD/b4Wg/TZtpP02baT9Nm2k/v1RqP79Uaj+/VGo/MQ5r'
        'PzEOaz8xDms/o8drP6PHaz+jx2s/FoFsPxaBbD8WgWw/iDptP4g6bT+IOm0/+vNtP/rzbT/6820/bK1uP2yt'
        'bj9srW4/3mZvP95mbz/eZm8/USBwP1EgcD9RIHA/w9lwP8PZcD/D2XA/xFpxP8RacT/EWnE/ttNxP7bTcT+2'
        '03E/p0xyP6dMcj+nTHI/mMVyP5jFcj+YxXI/ij5zP4o+cz+KPnM/e7dzP3u3cz97t3M/bTB0P20wdD9tMHQ/'
        'Xql0P16pdD9eqXQ/TyJ1P08idT9PInU/QZt1P0GbdT9Bm3U/MhR2PzIUdj8yFHY/JI12PySNdj8kjXY/FQZ3'
        'PxUGdz8VBnc/B393Pwd/dz8Hf3c/+Pd3P/j3dz/493c/6XB4P+lweD/pcHg/2+l4P9vpeD/b6Xg/zGJ5P8xi'
        'eT/MYnk/vtt5P77beT++23k/r1R6P69Uej+vVHo/oM16P6DNej+gzXo/kkZ7P5JGez+SRns/g797P4O/ez+D'
        'v3s/dTh8P3U4fD91OHw/ZrF8P2axfD9msXw/WCp9P1gqfT9YKn0/SaN9P0mjfT9Jo30/Ohx+Pzocfj86HH4/'
        'LJV+PyyVfj8slX4/HQ5/Px0Ofz8dDn8/D4d/Pw+Hfz8Ph38/AACAPwAAgD8AAIA/'
    ),
}

#: the maps this project names (``--cmap``'s help)
NAMES = ("terrain", "viridis", "cividis", "gist_earth", "Greys_r")

_CACHE: dict[str, np.ndarray] = {}


def table(name: str) -> np.ndarray | None:
    """The map's (256, 3) float32 colours, or None for a map not held here."""
    if name not in TABLE:
        return None
    if name not in _CACHE:
        lut = np.frombuffer(base64.b64decode(TABLE[name]), np.float32).reshape(N, 3)
        lut.flags.writeable = False
        _CACHE[name] = lut
    return _CACHE[name]


def colours(name: str, x: np.ndarray) -> np.ndarray | None:
    """RGB float64 (``x.shape + (3,)``) of the map ``name`` at the fractions ``x`` (floats),
    as matplotlib's ``colormaps[name](x)[..., :3]`` gives them rounded to float32 (the
    colours' precision in a texture); None for a map not held here.

    As matplotlib: the fraction ``x`` picks colour ``int(x · 256)`` (1 the last), below 0
    the first, above 1 the last, NaN black (its "bad" colour, transparent there).
    """
    lut = table(name)
    if lut is None:
        return None
    xa = np.array(x, copy=True)
    if xa.dtype.kind != "f":
        xa = xa.astype(np.float64)
    xa *= N
    xa[xa == N] = N - 1
    bad = np.isnan(xa)
    idx = np.clip(np.where(bad, 0.0, np.clip(xa, -1.0, N)), 0, N - 1).astype(np.intp)
    out = lut[idx].astype(np.float64)
    out[bad] = 0.0
    return out


def _tables() -> dict[str, str]:
    """The table, from matplotlib's maps (their colours at indices 0 … 255)."""
    import matplotlib

    out = {}
    for name in NAMES:
        cm = matplotlib.colormaps[name]
        assert cm.N == N, (name, cm.N)
        rgb = np.ascontiguousarray(np.asarray(cm(np.arange(N)))[:, :3], np.float32)
        out[name] = base64.b64encode(rgb.tobytes()).decode("ascii")
    return out


def main() -> None:
    """Print the ``TABLE`` of this module, computed from matplotlib."""
    lines = ["#: the maps' 256 colours: float32 RGB rows, base64 (computed by main())",
             "TABLE = {"]
    for name, s in _tables().items():
        lines.append(f"    {name!r}: (")
        lines += [f"        {s[k:k + 84]!r}" for k in range(0, len(s), 84)]
        lines.append("    ),")
    lines.append("}")
    sys.stdout.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
