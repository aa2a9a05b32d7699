/* The container's FMI 2.0 functions as internal ones, for the FMI 3.0 container.
 *
 * In an FMI 3.0 container (container_data.h defines CT_FMI_VERSION 3), container.c is
 * compiled with its FMI 2.0 API renamed ct2_fmi2Instantiate, ct2_fmi2DoStep, ...: the
 * binary exports the FMI 3.0 functions of container_fmi3.c, which call these, and no
 * fmi2 function of its own (the inner units' are uN_fmi2..., jfmu_names.h).
 * Included after fmi2Functions.h, whose macros name the functions without a prefix.
 */
#ifndef CONTAINER_FMI2_H
#define CONTAINER_FMI2_H

#undef fmi2GetTypesPlatform
#define fmi2GetTypesPlatform ct2_fmi2GetTypesPlatform
#undef fmi2GetVersion
#define fmi2GetVersion ct2_fmi2GetVersion
#undef fmi2SetDebugLogging
#define fmi2SetDebugLogging ct2_fmi2SetDebugLogging
#undef fmi2Instantiate
#define fmi2Instantiate ct2_fmi2Instantiate
#undef fmi2FreeInstance
#define fmi2FreeInstance ct2_fmi2FreeInstance
#undef fmi2SetupExperiment
#define fmi2SetupExperiment ct2_fmi2SetupExperiment
#undef fmi2EnterInitializationMode
#define fmi2EnterInitializationMode ct2_fmi2EnterInitializationMode
#undef fmi2ExitInitializationMode
#define fmi2ExitInitializationMode ct2_fmi2ExitInitializationMode
#undef fmi2Terminate
#define fmi2Terminate ct2_fmi2Terminate
#undef fmi2Reset
#define fmi2Reset ct2_fmi2Reset
#undef fmi2GetReal
#define fmi2GetReal ct2_fmi2GetReal
#undef fmi2GetInteger
#define fmi2GetInteger ct2_fmi2GetInteger
#undef fmi2GetBoolean
#define fmi2GetBoolean ct2_fmi2GetBoolean
#undef fmi2GetString
#define fmi2GetString ct2_fmi2GetString
#undef fmi2SetReal
#define fmi2SetReal ct2_fmi2SetReal
#undef fmi2SetInteger
#define fmi2SetInteger ct2_fmi2SetInteger
#undef fmi2SetBoolean
#define fmi2SetBoolean ct2_fmi2SetBoolean
#undef fmi2SetString
#define fmi2SetString ct2_fmi2SetString
#undef fmi2DoStep
#define fmi2DoStep ct2_fmi2DoStep
#undef fmi2CancelStep
#define fmi2CancelStep ct2_fmi2CancelStep
#undef fmi2GetStatus
#define fmi2GetStatus ct2_fmi2GetStatus
#undef fmi2GetRealStatus
#define fmi2GetRealStatus ct2_fmi2GetRealStatus
#undef fmi2GetIntegerStatus
#define fmi2GetIntegerStatus ct2_fmi2GetIntegerStatus
#undef fmi2GetBooleanStatus
#define fmi2GetBooleanStatus ct2_fmi2GetBooleanStatus
#undef fmi2GetStringStatus
#define fmi2GetStringStatus ct2_fmi2GetStringStatus
#undef fmi2SetRealInputDerivatives
#define fmi2SetRealInputDerivatives ct2_fmi2SetRealInputDerivatives
#undef fmi2GetRealOutputDerivatives
#define fmi2GetRealOutputDerivatives ct2_fmi2GetRealOutputDerivatives
#undef fmi2GetDirectionalDerivative
#define fmi2GetDirectionalDerivative ct2_fmi2GetDirectionalDerivative
#undef fmi2GetFMUstate
#define fmi2GetFMUstate ct2_fmi2GetFMUstate
#undef fmi2SetFMUstate
#define fmi2SetFMUstate ct2_fmi2SetFMUstate
#undef fmi2FreeFMUstate
#define fmi2FreeFMUstate ct2_fmi2FreeFMUstate
#undef fmi2SerializedFMUstateSize
#define fmi2SerializedFMUstateSize ct2_fmi2SerializedFMUstateSize
#undef fmi2SerializeFMUstate
#define fmi2SerializeFMUstate ct2_fmi2SerializeFMUstate
#undef fmi2DeSerializeFMUstate
#define fmi2DeSerializeFMUstate ct2_fmi2DeSerializeFMUstate

fmi2GetTypesPlatformTYPE fmi2GetTypesPlatform;
fmi2GetVersionTYPE fmi2GetVersion;
fmi2SetDebugLoggingTYPE fmi2SetDebugLogging;
fmi2InstantiateTYPE fmi2Instantiate;
fmi2FreeInstanceTYPE fmi2FreeInstance;
fmi2SetupExperimentTYPE fmi2SetupExperiment;
fmi2EnterInitializationModeTYPE fmi2EnterInitializationMode;
fmi2ExitInitializationModeTYPE fmi2ExitInitializationMode;
fmi2TerminateTYPE fmi2Terminate;
fmi2ResetTYPE fmi2Reset;
fmi2GetRealTYPE fmi2GetReal;
fmi2GetIntegerTYPE fmi2GetInteger;
fmi2GetBooleanTYPE fmi2GetBoolean;
fmi2GetStringTYPE fmi2GetString;
fmi2SetRealTYPE fmi2SetReal;
fmi2SetIntegerTYPE fmi2SetInteger;
fmi2SetBooleanTYPE fmi2SetBoolean;
fmi2SetStringTYPE fmi2SetString;
fmi2DoStepTYPE fmi2DoStep;
fmi2CancelStepTYPE fmi2CancelStep;
fmi2GetStatusTYPE fmi2GetStatus;
fmi2GetRealStatusTYPE fmi2GetRealStatus;
fmi2GetIntegerStatusTYPE fmi2GetIntegerStatus;
fmi2GetBooleanStatusTYPE fmi2GetBooleanStatus;
fmi2GetStringStatusTYPE fmi2GetStringStatus;
fmi2SetRealInputDerivativesTYPE fmi2SetRealInputDerivatives;
fmi2GetRealOutputDerivativesTYPE fmi2GetRealOutputDerivatives;
fmi2GetDirectionalDerivativeTYPE fmi2GetDirectionalDerivative;
fmi2GetFMUstateTYPE fmi2GetFMUstate;
fmi2SetFMUstateTYPE fmi2SetFMUstate;
fmi2FreeFMUstateTYPE fmi2FreeFMUstate;
fmi2SerializedFMUstateSizeTYPE fmi2SerializedFMUstateSize;
fmi2SerializeFMUstateTYPE fmi2SerializeFMUstate;
fmi2DeSerializeFMUstateTYPE fmi2DeSerializeFMUstate;

/* The value reference of the independent variable time (fmi3xml: after every other). */
extern const unsigned int ct2_time_vr;
/* The container's modelIdentifier, for messages. */
extern const char *const ct2_model_identifier;

#endif
