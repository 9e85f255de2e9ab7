% Intrinsic and Extrinsic Camera Parameters
%
% This script file can be directly executed under Matlab to recover the camera intrinsic and extrinsic parameters.
% IMPORTANT: This file contains neither the structure of the calibration objects nor the image coordinates of the calibration points.
%            All those complementary variables are saved in the complete matlab data file Calib_Results.mat.
% For more information regarding the calibration model visit http://www.vision.caltech.edu/bouguetj/calib_doc/


%-- Focal length:
fc = [ 970.309999999999945 ; 973.120000000000005 ];

%-- Principal point:
cc = [ 509.420000000000016 ; 393.540000000000020 ];

%-- Skew coefficient:
alpha_c = 0.000000000000000;

%-- Distortion coefficients:
kc = [ -0.184290000000000 ; 0.177180000000000 ; 0.000790000000000 ; -0.000560000000000 ; 0.000000000000000 ];

%-- Focal length uncertainty:
fc_error = [ 2.250000000000000 ; 2.190000000000000 ];

%-- Principal point uncertainty:
cc_error = [ 2.450000000000000 ; 1.870000000000000 ];

%-- Skew coefficient uncertainty:
alpha_c_error = 0.000000000000000;

%-- Distortion coefficients uncertainty:
kc_error = [ 0.006100000000000 ; 0.030200000000000 ; 0.000600000000000 ; 0.000500000000000 ; 0.000000000000000 ];

%-- Image size:
nx = 1024;
ny = 768;


%-- Various other variables (may be ignored if you do not use the Matlab Calibration Toolbox):
%-- Those variables are used to control which intrinsic parameters should be optimized

n_ima = 25;						% Number of calibration images
est_fc = [ 1 ; 1 ];					% Estimation indicator of the two focal variables
est_aspect_ratio = 1;				% Estimation indicator of the aspect ratio fc(2)/fc(1)
center_optim = 1;					% Estimation indicator of the principal point
est_alpha = 0;						% Estimation indicator of the skew coefficient
est_dist = [ 1 ; 1 ; 1 ; 1 ; 0 ];	% Estimation indicator of the distortion coefficients


%-- Extrinsic parameters:
%-- The rotation (omc_kk) and the translation (Tc_kk) vectors for every calibration image and their uncertainties

%-- Image #1:
omc_1 = [ 6.715252e-01 ; 6.266081e-01 ; -9.606421e-02 ];
Tc_1  = [ -1.064493e+02 ; -4.914872e+01 ; 4.033801e+02 ];
omc_error_1 = [ 4.029151e-03 ; 3.759649e-03 ; 5.763852e-04 ];
Tc_error_1  = [ 2.128986e+00 ; 9.829745e-01 ; 8.067601e+00 ];

%-- Image #2:
omc_2 = [ 3.083463e-01 ; 3.867838e-01 ; -2.361675e-01 ];
Tc_2  = [ 1.231041e+02 ; -6.467068e+01 ; 4.714782e+02 ];
omc_error_2 = [ 1.850078e-03 ; 2.320703e-03 ; 1.417005e-03 ];
Tc_error_2  = [ 2.462083e+00 ; 1.293414e+00 ; 9.429564e+00 ];

%-- Image #3:
omc_3 = [ -1.013306e+00 ; 1.210093e+00 ; 2.261948e-01 ];
Tc_3  = [ 3.702341e+01 ; 5.673696e+01 ; 6.663120e+02 ];
omc_error_3 = [ 6.079836e-03 ; 7.260556e-03 ; 1.357169e-03 ];
Tc_error_3  = [ 7.404683e-01 ; 1.134739e+00 ; 1.332624e+01 ];

%-- Image #4:
omc_4 = [ 8.104531e-01 ; -1.310163e+00 ; 1.579340e-01 ];
Tc_4  = [ -1.292611e+02 ; -1.386919e+01 ; 5.592416e+02 ];
omc_error_4 = [ 4.862719e-03 ; 7.860977e-03 ; 9.476038e-04 ];
Tc_error_4  = [ 2.585221e+00 ; 2.773839e-01 ; 1.118483e+01 ];

%-- Image #5:
omc_5 = [ NaN ; NaN ; NaN ];
Tc_5  = [ NaN ; NaN ; NaN ];
omc_error_5 = [ NaN ; NaN ; NaN ];
Tc_error_5  = [ NaN ; NaN ; NaN ];

%-- Image #6:
omc_6 = [ 1.134801e+00 ; -1.529288e+00 ; -1.341734e-01 ];
Tc_6  = [ -1.735480e+01 ; 2.620368e+01 ; 5.639736e+02 ];
omc_error_6 = [ 6.808807e-03 ; 9.175730e-03 ; 8.050405e-04 ];
Tc_error_6  = [ 3.470960e-01 ; 5.240736e-01 ; 1.127947e+01 ];

%-- Image #7:
omc_7 = [ -2.285749e+00 ; 1.255192e-01 ; 1.768917e-01 ];
Tc_7  = [ 7.638240e+01 ; 5.775686e+01 ; 8.235255e+02 ];
omc_error_7 = [ 1.371449e-02 ; 7.531151e-04 ; 1.061350e-03 ];
Tc_error_7  = [ 1.527648e+00 ; 1.155137e+00 ; 1.647051e+01 ];

%-- Image #8:
omc_8 = [ -1.389841e-01 ; -1.849453e+00 ; 1.073931e-01 ];
Tc_8  = [ -9.100647e+01 ; 1.043330e+01 ; 7.211026e+02 ];
omc_error_8 = [ 8.339045e-04 ; 1.109672e-02 ; 6.443589e-04 ];
Tc_error_8  = [ 1.820129e+00 ; 2.086661e-01 ; 1.442205e+01 ];

%-- Image #9:
omc_9 = [ -5.466441e-01 ; -8.907692e-01 ; -6.858940e-02 ];
Tc_9  = [ 9.469992e+01 ; 7.953384e+00 ; 7.477395e+02 ];
omc_error_9 = [ 3.279864e-03 ; 5.344615e-03 ; 4.115364e-04 ];
Tc_error_9  = [ 1.893998e+00 ; 1.590677e-01 ; 1.495479e+01 ];

%-- Image #10:
omc_10 = [ 9.771890e-01 ; 1.617177e+00 ; 2.299821e-01 ];
Tc_10  = [ 1.310346e+02 ; -1.200241e+02 ; 7.572037e+02 ];
omc_error_10 = [ 5.863134e-03 ; 9.703063e-03 ; 1.379893e-03 ];
Tc_error_10  = [ 2.620691e+00 ; 2.400482e+00 ; 1.514407e+01 ];

%-- Image #11:
omc_11 = [ 1.446940e+00 ; -6.348726e-01 ; 1.380706e-01 ];
Tc_11  = [ 1.811825e+01 ; 2.056644e+01 ; 5.387366e+02 ];
omc_error_11 = [ 8.681642e-03 ; 3.809236e-03 ; 8.284236e-04 ];
Tc_error_11  = [ 3.623650e-01 ; 4.113287e-01 ; 1.077473e+01 ];

%-- Image #12:
omc_12 = [ -5.213009e-01 ; -2.798590e-02 ; 1.596595e-01 ];
Tc_12  = [ 6.671979e+01 ; -5.715162e+01 ; 6.248641e+02 ];
omc_error_12 = [ 3.127805e-03 ; 1.679154e-04 ; 9.579572e-04 ];
Tc_error_12  = [ 1.334396e+00 ; 1.143032e+00 ; 1.249728e+01 ];

%-- Image #13:
omc_13 = [ -1.167667e+00 ; -1.861490e+00 ; 1.785171e-01 ];
Tc_13  = [ 1.485401e+02 ; -6.128321e+00 ; 5.051229e+02 ];
omc_error_13 = [ 7.006004e-03 ; 1.116894e-02 ; 1.071103e-03 ];
Tc_error_13  = [ 2.970803e+00 ; 1.225664e-01 ; 1.010246e+01 ];

%-- Image #14:
omc_14 = [ -8.076532e-01 ; -1.110693e-01 ; 1.220983e-01 ];
Tc_14  = [ -2.937079e+01 ; -5.691565e+01 ; 8.385206e+02 ];
omc_error_14 = [ 4.845919e-03 ; 6.664157e-04 ; 7.325897e-04 ];
Tc_error_14  = [ 5.874157e-01 ; 1.138313e+00 ; 1.677041e+01 ];

%-- Image #15:
omc_15 = [ 2.168092e+00 ; 2.247752e-02 ; 9.942337e-02 ];
Tc_15  = [ 8.774544e+01 ; 6.719097e+01 ; 6.894620e+02 ];
omc_error_15 = [ 1.300855e-02 ; 1.348651e-04 ; 5.965402e-04 ];
Tc_error_15  = [ 1.754909e+00 ; 1.343819e+00 ; 1.378924e+01 ];

%-- Image #16:
omc_16 = [ -1.286815e+00 ; -1.389738e+00 ; -2.905251e-01 ];
Tc_16  = [ 8.471642e+01 ; 1.261518e+02 ; 5.003468e+02 ];
omc_error_16 = [ 7.720890e-03 ; 8.338430e-03 ; 1.743151e-03 ];
Tc_error_16  = [ 1.694328e+00 ; 2.523036e+00 ; 1.000694e+01 ];

%-- Image #17:
omc_17 = [ 2.016240e+00 ; 1.028149e+00 ; 1.780352e-01 ];
Tc_17  = [ -9.928869e+01 ; 6.875230e+01 ; 8.608625e+02 ];
omc_error_17 = [ 1.209744e-02 ; 6.168891e-03 ; 1.068211e-03 ];
Tc_error_17  = [ 1.985774e+00 ; 1.375046e+00 ; 1.721725e+01 ];

%-- Image #18:
omc_18 = [ 6.017801e-01 ; 1.486264e+00 ; 9.666880e-02 ];
Tc_18  = [ 1.148272e+02 ; 1.030903e+02 ; 6.629538e+02 ];
omc_error_18 = [ 3.610681e-03 ; 8.917584e-03 ; 5.800128e-04 ];
Tc_error_18  = [ 2.296545e+00 ; 2.061806e+00 ; 1.325908e+01 ];

%-- Image #19:
omc_19 = [ 5.397378e-02 ; 3.065507e-02 ; 4.650806e-02 ];
Tc_19  = [ -4.516692e+01 ; 6.021957e+01 ; 5.852593e+02 ];
omc_error_19 = [ 3.238427e-04 ; 1.839304e-04 ; 2.790484e-04 ];
Tc_error_19  = [ 9.033384e-01 ; 1.204391e+00 ; 1.170519e+01 ];

%-- Image #20:
omc_20 = [ -7.247300e-01 ; 8.695935e-01 ; -1.376773e-01 ];
Tc_20  = [ 1.311395e+02 ; -3.278407e+01 ; 8.335826e+02 ];
omc_error_20 = [ 4.348380e-03 ; 5.217561e-03 ; 8.260635e-04 ];
Tc_error_20  = [ 2.622789e+00 ; 6.556814e-01 ; 1.667165e+01 ];

%-- Image #21:
omc_21 = [ 8.599072e-02 ; 3.183876e-01 ; -1.962943e-01 ];
Tc_21  = [ 1.208732e+02 ; 3.102414e+01 ; 6.433431e+02 ];
omc_error_21 = [ 5.159443e-04 ; 1.910325e-03 ; 1.177766e-03 ];
Tc_error_21  = [ 2.417464e+00 ; 6.204828e-01 ; 1.286686e+01 ];

%-- Image #22:
omc_22 = [ 1.825175e+00 ; -5.120239e-01 ; -1.680940e-02 ];
Tc_22  = [ 7.339202e+01 ; -6.142007e+01 ; 6.896815e+02 ];
omc_error_22 = [ 1.095105e-02 ; 3.072144e-03 ; 1.008564e-04 ];
Tc_error_22  = [ 1.467840e+00 ; 1.228401e+00 ; 1.379363e+01 ];

%-- Image #23:
omc_23 = [ -1.928670e+00 ; -1.879014e+00 ; 9.152920e-02 ];
Tc_23  = [ 7.010076e+01 ; -3.125470e+01 ; 4.215864e+02 ];
omc_error_23 = [ 1.157202e-02 ; 1.127409e-02 ; 5.491752e-04 ];
Tc_error_23  = [ 1.402015e+00 ; 6.250939e-01 ; 8.431728e+00 ];

%-- Image #24:
omc_24 = [ 2.110199e+00 ; 2.091635e-01 ; 2.359055e-02 ];
Tc_24  = [ -1.455668e+02 ; -8.998638e+01 ; 7.244511e+02 ];
omc_error_24 = [ 1.266119e-02 ; 1.254981e-03 ; 1.415433e-04 ];
Tc_error_24  = [ 2.911336e+00 ; 1.799728e+00 ; 1.448902e+01 ];

%-- Image #25:
omc_25 = [ -1.228559e+00 ; 3.522691e-01 ; -2.171374e-01 ];
Tc_25  = [ 4.272102e+01 ; -2.270467e+01 ; 8.140974e+02 ];
omc_error_25 = [ 7.371351e-03 ; 2.113615e-03 ; 1.302824e-03 ];
Tc_error_25  = [ 8.544203e-01 ; 4.540933e-01 ; 1.628195e+01 ];
