/PROG  WELD_SEAM
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "postproc sample";
PROG_SIZE	= 1210;
CREATE		= DATE 26-01-05  TIME 09:00:00;
MODIFIED	= DATE 26-01-05  TIME 09:00:00;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 9;
MEMORY_SIZE	= 1614;
PROTECT		= READ_WRITE;
TCD:  STACK_SIZE	= 0,
      TASK_PRIORITY	= 50,
      TIME_SLICE	= 0,
      BUSY_LAMP_OFF	= 0,
      ABORT_REQUEST	= 0,
      PAUSE_REQUEST	= 0;
DEFAULT_GROUP	= 1,*,*,*,*;
CONTROL_CODE	= 00000000 00000000;
/MN
   1:  UFRAME_NUM=1 ;
   2:  UTOOL_NUM=1 ;
   3:J P[1:"home"] 50% FINE    ;
   4:L P[2] 500mm/sec CNT50    ;
   5:  ! weld the seam ;
   6:L P[3] 20mm/sec FINE    ;
   7:C P[4]    
    :  P[5] 20mm/sec FINE    ;
   8:L P[3] 100mm/sec FINE Offset,PR[1]    ;
   9:J PR[2] 50% FINE    ;
/POS
P[1:"home"]{
   GP1:
	UF : 1, UT : 1,	
	J1=     0.000 deg,	J2=   -10.000 deg,	J3=    20.000 deg,
	J4=     0.000 deg,	J5=   -80.000 deg,	J6=     0.000 deg
};
P[2]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =   250.000  mm,	Y =  -120.500  mm,	Z =   300.000  mm,
	W =   180.000 deg,	P =     0.000 deg,	R =    90.000 deg
};
P[3]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =   250.000  mm,	Y =  -120.500  mm,	Z =   180.250  mm,
	W =   180.000 deg,	P =     0.000 deg,	R =    90.000 deg
};
P[4]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =   300.000  mm,	Y =   -80.000  mm,	Z =   180.250  mm,
	W =  -175.000 deg,	P =     5.000 deg,	R =    85.000 deg
};
P[5]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =   350.000  mm,	Y =  -120.500  mm,	Z =   180.250  mm,
	W =   180.000 deg,	P =     0.000 deg,	R =    90.000 deg
};
/END
