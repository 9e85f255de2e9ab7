% Stereo calibration parameters after optimization (go_calib_stereo printout):
fc_left = [ 1150.24  1151.78 ] ± [ 2.3  2.2 ]
cc_left = [ 639.5  479.5 ] ± [ 1.1  1.0 ]
alpha_c_left = [ 0.00000 ] ± [ 0.00000 ]
kc_left = [ -0.21  0.17  0.0004  -0.0002  0.00000 ] ± [ 0.001 0.002 0.0001 0.0001 0.00000 ]
om = [ 0.00312  -0.01045  0.00151 ] ± [ 0.0001 0.0001 0.0001 ]
T = [ -120.1  0.35  1.92 ] ± [ 0.05 0.04 0.2 ]
